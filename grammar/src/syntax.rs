//! The pest parser, and the translation of pest's errors into [`ParseError`]s that
//! name real tokens: "expected `;` or an operator, found `foo`".

use crate::ast::Span;
use crate::error::ParseError;
use pest::error::{ErrorVariant, InputLocation};

#[derive(pest_derive::Parser)]
#[grammar = "psg.pest"]
pub(crate) struct PsgParser;

/// Words that can never be names (kept in sync with `keyword` in psg.pest).
pub(crate) const KEYWORDS: [&str; 17] = [
    "import",
    "const",
    "fn",
    "graph",
    "let",
    "var",
    "for",
    "in",
    "if",
    "else",
    "true",
    "false",
    "param",
    "node",
    "output",
    "category",
    "description",
];

/// How an expected token is shown, and in which group of the "expected" list.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Group {
    /// A specific token: `;`, `)`, `fn` — the most useful suggestions come first.
    Token,
    /// A class of tokens: a name, an expression, a type.
    Class,
    Operator,
    EndOfFile,
}

fn describe(rule: Rule) -> (Group, &'static str) {
    use Group::*;
    match rule {
        Rule::semi => (Token, "`;`"),
        Rule::comma => (Token, "`,`"),
        Rule::colon => (Token, "`:`"),
        Rule::dotdot => (Token, "`..`"),
        Rule::dot | Rule::field_access => (Token, "`.`"),
        Rule::arrow => (Token, "`->`"),
        Rule::lparen => (Token, "`(`"),
        Rule::rparen => (Token, "`)`"),
        Rule::lbrace | Rule::block | Rule::loop_body => (Token, "`{`"),
        Rule::rbrace => (Token, "`}`"),
        Rule::lbracket | Rule::range => (Token, "`[`"),
        Rule::rbracket => (Token, "`]`"),
        Rule::assign => (Token, "`=`"),
        Rule::kw_import | Rule::import => (Token, "`import`"),
        Rule::kw_const | Rule::const_def | Rule::graph_const => (Token, "`const`"),
        Rule::kw_fn | Rule::fn_def => (Token, "`fn`"),
        Rule::kw_graph | Rule::graph_def => (Token, "`graph`"),
        Rule::kw_let => (Token, "`let`"),
        Rule::kw_var => (Token, "`var`"),
        Rule::let_stmt => (Token, "`let`, `var`"),
        Rule::kw_for | Rule::for_stmt => (Token, "`for`"),
        Rule::kw_in => (Token, "`in`"),
        Rule::kw_if | Rule::if_expr => (Token, "`if`"),
        Rule::kw_else => (Token, "`else`"),
        Rule::kw_param | Rule::param => (Token, "`param`"),
        Rule::kw_node | Rule::node => (Token, "`node` or `let`"),
        Rule::kw_output | Rule::output => (Token, "`output`"),
        Rule::kw_category | Rule::category => (Token, "`category`"),
        Rule::kw_description | Rule::description => (Token, "`description`"),
        Rule::kw_int => (Token, "`int`"),
        Rule::kw_true | Rule::kw_false | Rule::bool_lit => (Class, "`true` or `false`"),
        Rule::assign_op => (Class, "`=`, `+=`, `-=`, `*=` or `/=`"),
        Rule::ident | Rule::name | Rule::assign_stmt => (Class, "a name"),
        Rule::type_name | Rule::record_type | Rule::field_type => (Class, "a type"),
        Rule::float_lit | Rule::int_lit => (Class, "a number"),
        Rule::string => (Class, "a string"),
        Rule::op_or
        | Rule::op_and
        | Rule::op_eq
        | Rule::op_ne
        | Rule::op_le
        | Rule::op_lt
        | Rule::op_ge
        | Rule::op_gt
        | Rule::op_add
        | Rule::op_sub
        | Rule::op_mul
        | Rule::op_div
        | Rule::op_rem => (Operator, "an operator"),
        Rule::EOI => (EndOfFile, "end of file"),
        // Everything else can start an expression (or is one).
        _ => (Class, "an expression"),
    }
}

/// Labels that, when all present, are summarised as one entry.
const ITEM_STARTS: [&str; 4] = ["`import`", "`const`", "`fn`", "`graph`"];
const MEMBER_STARTS: [&str; 6] = ["`category`", "`description`", "`param`", "`node` or `let`", "`const`", "`output`"];

/// Turns a pest failure on `src` into our error; spans are shifted by `base`.
pub(crate) fn translate(error: pest::error::Error<Rule>, src: &str, base: usize) -> ParseError {
    let at = match error.location {
        InputLocation::Pos(at) => at,
        InputLocation::Span((start, _)) => start,
    };
    let at = at.min(src.len());
    match error.variant {
        ErrorVariant::ParsingError { positives, .. } => expected_found(&positives, src, at, base),
        // pest's own guards ("stack limit reached", "call limit reached").
        ErrorVariant::CustomError { message } => {
            ParseError::new(format!("the input is too complex to parse ({message})"), shift(token_at(src, at).0, base))
        }
    }
}

fn expected_found(positives: &[Rule], src: &str, at: usize, base: usize) -> ParseError {
    let mut labels: Vec<(Group, &str)> = Vec::new();
    for &rule in positives {
        let label = describe(rule);
        if !labels.contains(&label) {
            labels.push(label);
        }
    }
    summarise(&mut labels, &MEMBER_STARTS, "a graph member (`param`, `node`, `output`, …)");
    summarise(&mut labels, &ITEM_STARTS, "`import`, `const`, `fn` or `graph`");
    // An operator is always possible after a complete expression; listing the
    // postfix `.` and `(` as well would only add noise.
    if labels.iter().any(|&(group, _)| group == Group::Operator) {
        labels.retain(|&(_, text)| text != "`.`" && text != "`(`");
    }
    // A name is an expression (and `true` or `false` too).
    if labels.iter().any(|&(_, text)| text == "an expression") {
        labels.retain(|&(_, text)| text != "a name" && text != "`true` or `false`");
    }
    labels.sort_by_key(|&(group, _)| group); // stable: keeps pest's order within a group

    let (span, found) = token_at(src, at);
    let expected: Vec<&str> = labels.iter().map(|&(_, text)| text).collect();
    let message = if expected.is_empty() {
        format!("unexpected {found}")
    } else {
        format!("expected {}, found {found}", join_or(&expected))
    };
    let mut error = ParseError::new(message, shift(span, base));
    error.hint = hint_for(&expected, src, span);
    error
}

fn summarise(labels: &mut Vec<(Group, &str)>, members: &[&str], summary: &'static str) {
    if members.iter().all(|m| labels.iter().any(|&(_, text)| text == *m)) {
        let first = labels.iter().position(|&(_, text)| members.contains(&text)).unwrap_or(0);
        labels.retain(|&(_, text)| !members.contains(&text));
        labels.insert(first.min(labels.len()), (Group::Token, summary));
    }
}

fn hint_for(expected: &[&str], src: &str, found: Span) -> Option<String> {
    let found_text = &src[found.start..found.end];
    let is_word = found_text.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_');
    if KEYWORDS.contains(&found_text) && expected.contains(&"a name") {
        return Some(format!("`{found_text}` is a keyword and cannot be used as a name"));
    }
    if found_text == "int" && expected.contains(&"`in`") {
        return Some("`int` comes after the range: `param n = 4 in [1, 8] int`".to_owned());
    }
    if is_word && !KEYWORDS.contains(&found_text) && expected.iter().any(|e| e.starts_with("a graph member")) {
        return Some(format!(
            "graph members start with a keyword: `output {found_text} = …`, `node {found_text} = …`, `param {found_text} = …`"
        ));
    }
    if expected.contains(&"`;`") {
        // The usual cause: the previous line lacks its `;`.
        let previous = src[..found.start].trim_end();
        if !previous.is_empty() && src[previous.len()..found.start].contains('\n') {
            let (line, _) = crate::error::line_col(src, previous.len());
            return Some(format!("is a `;` missing at the end of line {line}?"));
        }
    }
    if found_text == "}" && expected.contains(&"`let`, `var`") && expected.contains(&"an expression") {
        return Some("a block ends with its value: an expression without `;`".to_owned());
    }
    if found_text == ";" && expected.first() == Some(&"`}`") {
        return Some("the last expression of a block is its value and takes no `;`".to_owned());
    }
    if found_text == "}" && expected.contains(&"`=`, `+=`, `-=`, `*=` or `/=`") {
        return Some(
            "a `for` body has no value: it holds only statements (`let`, `var`, assignments, `for`)".to_owned(),
        );
    }
    if expected.contains(&"`else`") {
        return Some("`if` is an expression: it needs an `else` branch".to_owned());
    }
    if expected.first() == Some(&"`->`") {
        return Some("a function declares its result type: `fn f(x: float) -> float { … }`".to_owned());
    }
    None
}

fn join_or(items: &[&str]) -> String {
    match items {
        [] => String::new(),
        [one] => (*one).to_owned(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

fn shift(span: Span, base: usize) -> Span {
    Span::new(span.start + base, span.end + base)
}

const MULTI_CHAR_PUNCTUATION: [&str; 12] = ["->", "..", "==", "!=", "<=", ">=", "&&", "||", "+=", "-=", "*=", "/="];

/// Longest token quoted whole in a message; longer ones are cut with an ellipsis.
const MAX_QUOTED_TOKEN: usize = 48;

/// The token starting at `at` (a char boundary): its span and how to show it.
pub(crate) fn token_at(src: &str, at: usize) -> (Span, String) {
    let rest = &src[at..];
    let Some(first) = rest.chars().next() else {
        return (Span::new(at, at), "end of file".to_owned());
    };
    let len = if first.is_ascii_alphanumeric() || first == '_' {
        // A word or a number (including `1.5e-3`, roughly: enough to show it).
        let mut len = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(rest.len());
        if first.is_ascii_digit() && rest[len..].starts_with('.') {
            let frac = &rest[len + 1..];
            let digits = frac.find(|c: char| !c.is_ascii_alphanumeric()).unwrap_or(frac.len());
            if digits > 0 {
                len += 1 + digits;
            }
        }
        len
    } else if first == '"' {
        rest[1..].find(['"', '\n']).map_or(rest.len(), |i| if rest.as_bytes()[1 + i] == b'"' { i + 2 } else { i + 1 })
    } else {
        MULTI_CHAR_PUNCTUATION.iter().find(|p| rest.starts_with(*p)).map_or(first.len_utf8(), |p| p.len())
    };
    let text = &rest[..len];
    let shown = if KEYWORDS.contains(&text) {
        format!("keyword `{text}`")
    } else if first == '"' {
        "a string".to_owned()
    } else if first.is_whitespace() || first.is_control() {
        format!("character U+{:04X}", first as u32)
    } else if text.len() > MAX_QUOTED_TOKEN {
        // A huge word (generated or hostile input) is named, not echoed: its span shows where.
        format!("`{}…`", &text[..text.floor_char_boundary(MAX_QUOTED_TOKEN)])
    } else {
        format!("`{text}`")
    };
    (Span::new(at, at + len), shown)
}
