//! OBJ + MTL loading through tobj: one material part per `usemtl` name (a part may span several
//! objects), texture coordinates in the OBJ convention (v up), generated planar UVs (1 unit =
//! 1 scene unit, projected along the dominant axis of each face) when `vt` is missing.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use glam::Vec3;

use psc_base::progress::{self, NoProgress, Progress};

use crate::RenderError;

/// What the MTL says about a part (used for default materials only; the fit ignores it).
#[derive(Clone, Debug, Default)]
pub struct PartMtl {
    pub kd: Option<[f32; 3]>,
    pub map_kd: Option<PathBuf>,
    pub map_normal: Option<PathBuf>,
    /// `Pr` (PBR extension) if present.
    pub roughness: Option<f32>,
}

/// A triangle mesh with per-vertex attributes and a part index per triangle.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals, same length as `positions`, or empty when the OBJ has none.
    pub normals: Vec<Vec3>,
    /// Per-vertex uv (OBJ convention), same length as `positions`.
    pub uvs: Vec<[f32; 2]>,
    pub triangles: Vec<[u32; 3]>,
    pub tri_part: Vec<u32>,
    pub part_names: Vec<String>,
    pub part_mtl: Vec<PartMtl>,
    /// Parts whose uvs were generated.
    pub generated_uv_parts: Vec<String>,
}

impl Mesh {
    pub fn part_index(&self, name: &str) -> Option<usize> {
        self.part_names.iter().position(|n| n == name)
    }

    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (lo, hi)
    }
}

/// A name in an OBJ and the (1-based) line it appears on.
type AtLine = (String, usize);

/// `usemtl` names (first use, with its line) and `mtllib` files (with their lines).
fn scan_obj(text: &str) -> (Vec<AtLine>, Vec<AtLine>) {
    let mut usemtl: Vec<AtLine> = Vec::new();
    let mut mtllibs = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("usemtl") => {
                let name = it.collect::<Vec<_>>().join(" ");
                if !usemtl.iter().any(|(n, _)| *n == name) {
                    usemtl.push((name, i + 1));
                }
            }
            Some("mtllib") => mtllibs.extend(it.map(|f| (f.to_string(), i + 1))),
            _ => {}
        }
    }
    (usemtl, mtllibs)
}

/// Counts the bytes the OBJ parser consumes, for progress.
struct Counting<'a> {
    inner: &'a [u8],
    progress: &'a dyn Progress,
}

impl std::io::Read for Counting<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.progress.advance(n as u64);
        Ok(n)
    }
}

/// Load an OBJ (and its MTL files, which must be in the OBJ's folder or below). Problems that
/// still allow a render become warnings.
pub fn load_obj(path: &Path, warnings: &mut Vec<String>) -> Result<Mesh, RenderError> {
    load_obj_with_progress(path, warnings, &NoProgress)
}

/// [`load_obj`], reporting the stage "loading `<file>`" in bytes parsed to `progress`.
pub fn load_obj_with_progress(
    path: &Path,
    warnings: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<Mesh, RenderError> {
    load_obj_in(path, path.parent().unwrap_or(Path::new(".")), warnings, progress)
}

/// [`load_obj_with_progress`] for an OBJ of the scene folder `root`: the MTL files and textures
/// it names must stay inside `root` (others are not read, with a warning).
pub fn load_obj_in(
    path: &Path,
    root: &Path,
    warnings: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<Mesh, RenderError> {
    let text = crate::json::read_text(path, "OBJ mesh")?;
    let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    progress::stage(progress, &format!("loading {name}"), Some(text.len() as u64), "bytes", || {
        load_obj_text(path, root, text, warnings, progress)
    })
}

/// `dir/file` if it stays inside `root` (see [`crate::scene::confined`]).
fn inside(root: &Path, dir: &Path, file: &str, what: &str) -> Result<PathBuf, RenderError> {
    match dir.strip_prefix(root) {
        Ok(rel_dir) => crate::scene::confined(root, &rel_dir.join(file).to_string_lossy(), what),
        Err(_) => crate::scene::confined(dir, file, what),
    }
}

fn load_obj_text(
    path: &Path,
    root: &Path,
    text: String,
    warnings: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<Mesh, RenderError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let (usemtl, mtllibs) = scan_obj(&text);
    let obj = path.display();

    // Read the MTL files ourselves (with line numbers in every warning), then add an empty
    // material for every usemtl name they lack, so that each usemtl name survives as a part
    // even with a missing or partial MTL.
    let mut materials: Vec<tobj::Material> = Vec::new();
    let mut read_any = false;
    for (lib, line) in &mtllibs {
        let p = match inside(root, dir, lib, "MTL file") {
            Ok(p) => p,
            Err(e) => {
                warnings.push(format!("{obj}:{line}: mtllib not read: {e}"));
                continue;
            }
        };
        match crate::json::read_text(&p, "MTL file") {
            Ok(t) => {
                read_any = true;
                materials.extend(crate::mtl::parse(&p, &t, warnings));
            }
            Err(e) => warnings.push(format!("{obj}:{line}: {e}; parts keep their usemtl names, default materials")),
        }
    }
    for m in &mut materials {
        for (tex, kind) in [(&mut m.diffuse_texture, "map_Kd texture"), (&mut m.normal_texture, "norm texture")] {
            if let Some(t) = tex.as_deref() {
                if let Err(e) = inside(root, dir, t, kind) {
                    warnings.push(format!("material '{}': {e}; not read", m.name));
                    *tex = None;
                }
            }
        }
    }
    for (name, line) in &usemtl {
        if !materials.iter().any(|m| &m.name == name) {
            if read_any {
                warnings.push(format!(
                    "{obj}:{line}: usemtl '{name}' is not defined in the MTL file(s); part '{name}' gets the default \
                     material"
                ));
            }
            materials.push(tobj::Material { name: name.clone(), ..Default::default() });
        }
    }
    // Every statement is checked here, before tobj: tobj finds some of these problems itself
    // (without a line), and drops others silently (a face's `vn` index when the file has no
    // normals at all), so the one check for the room model and the light meshes is this one.
    if let Some((line, problem, content)) = first_bad_line(&text) {
        return Err(RenderError::Obj { path: path.to_path_buf(), message: describe_bad_line(line, &problem, content) });
    }
    let synthetic = mtllibs.is_empty() && !usemtl.is_empty();
    let source = if synthetic { format!("mtllib __psc_synthetic.mtl\n{text}") } else { text };
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let mats_for_loader = materials.clone();
    // (A synthetic mtllib line adds a few bytes beyond the file's size to the count.)
    let mut reader = BufReader::new(Counting { inner: source.as_bytes(), progress });
    let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Ok((mats_for_loader.clone(), mats_for_loader.iter().enumerate().map(|(i, m)| (m.name.clone(), i)).collect()))
    })
    .map_err(|e| RenderError::Obj { path: path.to_path_buf(), message: format!("cannot parse the OBJ: {e}") })?;

    let mut mesh = Mesh::default();
    let mut any_normals = false;
    let mut degenerate = 0usize;
    for model in &models {
        let m = &model.mesh;
        let part_name = m
            .material_id
            .and_then(|i| materials.get(i))
            .map(|mat| mat.name.clone())
            .unwrap_or_else(|| "default".to_string());
        let part = match mesh.part_index(&part_name) {
            Some(i) => i,
            None => {
                let mtl = m.material_id.and_then(|i| materials.get(i));
                mesh.part_mtl.push(PartMtl {
                    kd: mtl.and_then(|x| x.diffuse),
                    map_kd: mtl.and_then(|x| x.diffuse_texture.as_ref()).map(|t| dir.join(t)),
                    map_normal: mtl.and_then(|x| x.normal_texture.as_ref()).map(|t| dir.join(t)),
                    roughness: mtl.and_then(|x| x.unknown_param.get("Pr")).and_then(|v| v.trim().parse().ok()),
                });
                mesh.part_names.push(part_name.clone());
                mesh.part_names.len() - 1
            }
        } as u32;
        let nv = m.positions.len() / 3;
        let pos: Vec<Vec3> =
            (0..nv).map(|i| Vec3::new(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2])).collect();
        let has_uv = m.texcoords.len() == 2 * nv && nv > 0;
        let has_n = m.normals.len() == 3 * nv && nv > 0;
        any_normals |= has_n;
        if !has_uv && !mesh.generated_uv_parts.contains(&part_name) {
            mesh.generated_uv_parts.push(part_name.clone());
            warnings.push(format!(
                "{}: part '{part_name}' (object '{}') has no texture coordinates (vt); generated planar UVs",
                path.display(),
                model.name
            ));
        }
        for tri in m.indices.chunks_exact(3) {
            let idx = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
            if idx.iter().any(|&i| i >= nv) {
                return Err(RenderError::Obj { path: path.to_path_buf(), message: "face index out of range".into() });
            }
            let p = [pos[idx[0]], pos[idx[1]], pos[idx[2]]];
            let ng = (p[1] - p[0]).cross(p[2] - p[0]);
            let area2 = ng.length_squared();
            if area2.is_nan() || area2 <= 1e-20 || !p.iter().all(|v| v.is_finite()) {
                degenerate += 1;
                continue;
            }
            // Vertices are not shared between triangles here: simple, and needed anyway for
            // per-face generated uvs. Meshes are coarse room models (thousands of triangles).
            let base = mesh.positions.len() as u32;
            let ngn = ng.normalize();
            let axis = ngn.abs();
            for (k, &i) in idx.iter().enumerate() {
                mesh.positions.push(p[k]);
                let uv = if has_uv {
                    [m.texcoords[2 * i], m.texcoords[2 * i + 1]]
                } else if axis.y >= axis.x && axis.y >= axis.z {
                    [p[k].x, p[k].z]
                } else if axis.x >= axis.z {
                    [p[k].z, p[k].y]
                } else {
                    [p[k].x, p[k].y]
                };
                mesh.uvs.push(uv);
                let n = if has_n {
                    Vec3::new(m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2])
                } else {
                    Vec3::ZERO
                };
                mesh.normals.push(n);
            }
            mesh.triangles.push([base, base + 1, base + 2]);
            mesh.tri_part.push(part);
        }
    }
    if !any_normals {
        mesh.normals.clear();
    } else {
        // Vertices without a usable normal fall back to their face normal.
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let _ = t;
            let p = tri.map(|i| mesh.positions[i as usize]);
            let ng = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            for &i in tri {
                let n = mesh.normals[i as usize];
                mesh.normals[i as usize] = if n.length_squared() > 1e-12 { n.normalize() } else { ng };
            }
        }
    }
    if degenerate > 0 {
        warnings
            .push(format!("{}: skipped {degenerate} degenerate (zero-area or non-finite) triangles", path.display()));
    }
    if mesh.triangles.is_empty() {
        return Err(RenderError::Obj { path: path.to_path_buf(), message: "no triangles".into() });
    }
    Ok(mesh)
}

/// The error for the first invalid statement: its line, what is wrong and (the start of) the line.
fn describe_bad_line(line: usize, problem: &str, content: &str) -> String {
    let shown: String = content.chars().take(80).collect();
    let more = if content.chars().count() > 80 { "…" } else { "" };
    format!("line {line}: {problem} (found '{shown}{more}')")
}

/// (1-based line, what is wrong, the line) of the first invalid statement: numbers where numbers
/// belong, face indices that refer to vertices, texture coordinates and normals defined before
/// them (tobj's errors carry no line, and it ignores normal indices of a file with no `vn`).
fn first_bad_line(text: &str) -> Option<(usize, String, &str)> {
    let (mut nv, mut nt, mut nn) = (0i64, 0i64, 0i64);
    let floats = |it: std::str::SplitWhitespace, min: usize, max: usize| {
        let v: Option<Vec<f32>> = it.map(|t| t.parse::<f32>().ok()).collect();
        v.is_some_and(|v| v.len() >= min && v.len() <= max)
    };
    // An index i of n defined so far: 1..=n, or -n..=-1 (relative); 0 is never valid.
    let index_ok = |t: &str, n: i64| t.parse::<i64>().is_ok_and(|i| (i >= 1 && i <= n) || (i < 0 && -i <= n));
    for (k, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        let Some(kw) = it.next() else { continue };
        let bad = |what: &str| Some((k + 1, what.to_string(), line.trim()));
        match kw {
            "v" => {
                if !floats(it, 3, 7) {
                    return bad("a vertex needs three numbers x y z");
                }
                nv += 1;
            }
            "vt" => {
                if !floats(it, 1, 3) {
                    return bad("a texture coordinate needs one to three numbers");
                }
                nt += 1;
            }
            "vn" => {
                if !floats(it, 3, 3) {
                    return bad("a normal needs three numbers");
                }
                nn += 1;
            }
            "f" | "l" | "p" => {
                let corners: Vec<&str> = it.collect();
                let need = match kw {
                    "f" => 3,
                    "l" => 2,
                    _ => 1,
                };
                if corners.len() < need {
                    return bad(&format!("'{kw}' needs at least {need} vertices"));
                }
                for c in corners {
                    let mut parts = c.split('/');
                    let v = parts.next().unwrap_or("");
                    if !index_ok(v, nv) {
                        return bad(&format!("vertex index '{v}' is not one of the {nv} vertices defined so far"));
                    }
                    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                        if !index_ok(t, nt) {
                            return bad(&format!(
                                "texture index '{t}' is not one of the {nt} texture coordinates defined so far"
                            ));
                        }
                    }
                    if let Some(n) = parts.next().filter(|n| !n.is_empty()) {
                        if !index_ok(n, nn) {
                            return bad(&format!("normal index '{n}' is not one of the {nn} normals defined so far"));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    None
}

/// Load an emitter mesh: triangles whose winding gives the emitting side. When the OBJ has
/// vertex normals and they disagree with the winding, the winding is flipped to follow them.
pub fn load_emitter(path: &Path, warnings: &mut Vec<String>) -> Result<Vec<[Vec3; 3]>, RenderError> {
    load_emitter_in(path, path.parent().unwrap_or(Path::new(".")), warnings)
}

/// [`load_emitter`] for an emitter of the scene folder `root` (see [`load_obj_in`]).
pub fn load_emitter_in(path: &Path, root: &Path, warnings: &mut Vec<String>) -> Result<Vec<[Vec3; 3]>, RenderError> {
    let mut local = Vec::new();
    let mesh = load_obj_in(path, root, &mut local, &NoProgress)?;
    // Missing uvs are irrelevant for an emitter; keep other warnings.
    warnings.extend(local.into_iter().filter(|w| !w.contains("no texture coordinates")));
    let mut tris = Vec::with_capacity(mesh.triangles.len());
    for tri in &mesh.triangles {
        let mut p = tri.map(|i| mesh.positions[i as usize]);
        if !mesh.normals.is_empty() {
            let navg: Vec3 = tri.iter().map(|&i| mesh.normals[i as usize]).sum();
            let ng = (p[1] - p[0]).cross(p[2] - p[0]);
            if ng.dot(navg) < 0.0 {
                p.swap(1, 2);
            }
        }
        tris.push(p);
    }
    Ok(tris)
}
