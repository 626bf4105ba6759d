//! Small HTML building blocks: escaping, numbers, tables, images and colour swatches. Every
//! piece of text from a file goes through [`esc`].

use std::fmt::Write;

/// `text` with the five HTML-special characters escaped (safe in text and in quoted attributes).
pub fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A number with four significant digits, in plain or scientific notation as fits.
pub fn num(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let a = x.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

/// A JSON value as short text: numbers through [`num`], arrays as `[a, b, c]`, strings bare.
pub fn value(v: &serde_json::Value) -> String {
    use serde_json::Value;
    match v {
        Value::Number(n) if n.is_i64() || n.is_u64() => n.to_string(),
        Value::Number(n) => n.as_f64().map(num).unwrap_or_else(|| n.to_string()),
        Value::String(s) => esc(s),
        Value::Array(a) => format!("[{}]", a.iter().map(value).collect::<Vec<_>>().join(", ")),
        Value::Null => "—".into(),
        other => esc(&other.to_string()),
    }
}

/// The sRGB hex colour of a linear RGB triple (each channel clamped to [0, 1]).
pub fn hex_of_linear(rgb: [f64; 3]) -> String {
    let c = |x: f64| (psc_base::color::linear_to_srgb(x as f32) * 255.0).round().clamp(0.0, 255.0) as u8;
    format!("#{:02x}{:02x}{:02x}", c(rgb[0]), c(rgb[1]), c(rgb[2]))
}

/// A small square of colour `hex` (an inline style: no external resource).
pub fn swatch(hex: &str) -> String {
    format!("<span class=\"sw\" style=\"background:{hex}\"></span>")
}

/// An `<img>` of a `data:` URI with its alternative text.
pub fn img(data_uri: &str, alt: &str, class: &str) -> String {
    format!("<img class=\"{class}\" src=\"{data_uri}\" alt=\"{}\">", esc(alt))
}

/// A figure: the image and a caption (already HTML).
pub fn figure(image_html: &str, caption_html: &str) -> String {
    format!("<figure>{image_html}<figcaption>{caption_html}</figcaption></figure>")
}

/// A "not available" note with the reason.
pub fn missing(what: &str, why: &str) -> String {
    format!("<p class=\"na\">{}: not available ({})</p>", esc(what), esc(why))
}

/// A table from a header and rows of cells that are already HTML.
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = String::from("<table><thead><tr>");
    for h in header {
        let _ = write!(s, "<th>{}</th>", esc(h));
    }
    s.push_str("</tr></thead><tbody>");
    for row in rows {
        s.push_str("<tr>");
        for cell in row {
            let _ = write!(s, "<td>{cell}</td>");
        }
        s.push_str("</tr>");
    }
    s.push_str("</tbody></table>");
    s
}

/// An HTML `id` for a section from a name (letters, digits, `-` and `_`; others `-`).
pub fn anchor(prefix: &str, name: &str) -> String {
    let body: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '-' }).collect();
    format!("{prefix}-{body}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_quotes() {
        assert_eq!(esc("<a href=\"x\">'&'</a>"), "&lt;a href=&quot;x&quot;&gt;&#39;&amp;&#39;&lt;/a&gt;");
    }

    #[test]
    fn numbers_keep_four_significant_digits() {
        assert_eq!(num(0.0072725), "0.007273");
        assert_eq!(num(41.03398), "41.03");
        assert_eq!(num(119.7012), "119.7");
        assert_eq!(num(2e-7), "2.000e-7");
        assert_eq!(num(0.0), "0");
    }

    #[test]
    fn swatch_colours_are_srgb() {
        assert_eq!(hex_of_linear([0.0, 1.0, 0.2159]), "#00ff80"); // sRGB 128.01
        assert_eq!(hex_of_linear([-1.0, 2.0, f64::NAN]), "#00ff00");
    }
}
