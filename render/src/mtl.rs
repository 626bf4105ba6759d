//! MTL files: the few statements the renderer uses (`newmtl`, `Kd`, `map_Kd`, `norm`, `Pr`),
//! read line by line so that every problem is a warning with the file and line, and one bad
//! line costs only that statement, not the whole file.
//!
//! Other standard MTL statements (`Ka`, `Ks`, `Ns`, `illum`, `map_Bump`, …) are accepted and
//! ignored. A file where no line is an MTL statement is reported as not being an MTL file.

use std::path::Path;

/// Statements of the MTL format the renderer ignores (accepted without a warning).
const IGNORED: &[&str] = &[
    "Ka",
    "Ks",
    "Ke",
    "Ns",
    "Ni",
    "d",
    "Tr",
    "Tf",
    "illum",
    "map_Ka",
    "map_Ks",
    "map_Ke",
    "map_Ns",
    "map_d",
    "map_Bump",
    "map_bump",
    "bump",
    "disp",
    "decal",
    "refl",
    "sharpness",
    "Pm",
    "Ps",
    "Pc",
    "Pcr",
    "aniso",
    "anisor",
    "map_Pr",
    "map_Pm",
    "map_Ps",
    "map_RMA",
    "map_ORM",
];

/// Parse the MTL text of `path` into tobj materials (name, diffuse, diffuse and normal
/// textures, `Pr` in `unknown_param`); problems become warnings naming `path` and the line.
pub fn parse(path: &Path, text: &str, warnings: &mut Vec<String>) -> Vec<tobj::Material> {
    let file = path.display();
    let mut materials: Vec<tobj::Material> = Vec::new();
    let mut current: Option<tobj::Material> = None;
    let (mut statements, mut foreign) = (0usize, Vec::new());
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (keyword, rest) = match line.split_once(char::is_whitespace) {
            Some((k, r)) => (k, r.trim()),
            None => (line, ""),
        };
        let at = |what: String| format!("{file}:{line_no}: {what}");
        if keyword == "newmtl" {
            statements += 1;
            if rest.is_empty() {
                warnings.push(at("newmtl without a name; the statements up to the next newmtl are ignored".into()));
                if let Some(m) = current.take() {
                    materials.push(m);
                }
                continue;
            }
            if let Some(m) = current.replace(tobj::Material { name: rest.to_string(), ..Default::default() }) {
                materials.push(m);
            }
            continue;
        }
        let known = matches!(keyword, "Kd" | "map_Kd" | "norm" | "Pr") || IGNORED.contains(&keyword);
        if !known {
            foreign.push(line_no);
            continue;
        }
        statements += 1;
        let Some(mat) = current.as_mut() else {
            warnings.push(at(format!("'{keyword}' before any newmtl; ignored")));
            continue;
        };
        match keyword {
            "Kd" => match numbers(rest, 3) {
                Some(v) => mat.diffuse = Some([v[0], v[1], v[2]]),
                None => warnings.push(at(format!(
                    "Kd of material '{}' must be three non-negative numbers, found '{rest}'; the material keeps \
                     the default Kd",
                    mat.name
                ))),
            },
            "Pr" => match numbers(rest, 1) {
                Some(v) if v[0] <= 1.0 => {
                    mat.unknown_param.insert("Pr".into(), rest.to_string());
                }
                _ => warnings.push(at(format!(
                    "Pr (roughness) of material '{}' must be a number in [0, 1], found '{rest}'; the material keeps \
                     the default roughness",
                    mat.name
                ))),
            },
            "map_Kd" | "norm" => {
                if rest.is_empty() {
                    warnings.push(at(format!("{keyword} of material '{}' names no file; ignored", mat.name)));
                } else if keyword == "map_Kd" {
                    mat.diffuse_texture = Some(rest.to_string());
                } else {
                    mat.normal_texture = Some(rest.to_string());
                }
            }
            _ => {}
        }
    }
    if let Some(m) = current {
        materials.push(m);
    }
    if statements == 0 && !foreign.is_empty() {
        warnings.push(format!(
            "{file}: not an MTL file (no line is an MTL statement; line {} starts with '{}'); its parts get \
             default materials",
            foreign[0],
            first_word(text, foreign[0])
        ));
    } else if !foreign.is_empty() {
        warnings.push(format!(
            "{file}:{}: {} line(s) with unknown statements (first: '{}'); ignored",
            foreign[0],
            foreign.len(),
            first_word(text, foreign[0])
        ));
    }
    materials
}

/// Exactly `n` finite, non-negative numbers.
fn numbers(s: &str, n: usize) -> Option<Vec<f32>> {
    let v: Vec<f32> = s.split_whitespace().map(|t| t.parse::<f32>().ok()).collect::<Option<Vec<f32>>>()?;
    (v.len() == n && v.iter().all(|x| x.is_finite() && *x >= 0.0)).then_some(v)
}

/// The first word of line `line_no` (1-based), at most 40 characters.
fn first_word(text: &str, line_no: usize) -> String {
    let line = text.lines().nth(line_no - 1).unwrap_or("");
    line.split_whitespace().next().unwrap_or("").chars().take(40).collect()
}
