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

fn scan_obj(text: &str) -> (Vec<String>, Vec<String>) {
    let mut usemtl = Vec::new();
    let mut mtllibs = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("usemtl") => {
                let name = it.collect::<Vec<_>>().join(" ");
                if !usemtl.contains(&name) {
                    usemtl.push(name);
                }
            }
            Some("mtllib") => mtllibs.extend(it.map(str::to_string)),
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

/// Load an OBJ (and its MTL files). Problems that still allow a render become warnings.
pub fn load_obj(path: &Path, warnings: &mut Vec<String>) -> Result<Mesh, RenderError> {
    load_obj_with_progress(path, warnings, &NoProgress)
}

/// [`load_obj`], reporting the stage "loading <file>" in bytes parsed to `progress`.
pub fn load_obj_with_progress(
    path: &Path,
    warnings: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<Mesh, RenderError> {
    let text = crate::json::read_text(path, "OBJ mesh")?;
    let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    progress::stage(progress, &format!("loading {name}"), Some(text.len() as u64), "bytes", || {
        load_obj_text(path, text, warnings, progress)
    })
}

fn load_obj_text(
    path: &Path,
    text: String,
    warnings: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<Mesh, RenderError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let (usemtl, mtllibs) = scan_obj(&text);

    // Load the MTL files ourselves, then add an empty material for every usemtl name they lack,
    // so that each usemtl name survives as a part even with a missing or partial MTL.
    let mut materials: Vec<tobj::Material> = Vec::new();
    for lib in &mtllibs {
        let p = dir.join(lib);
        match std::fs::File::open(&p) {
            Ok(f) => match tobj::load_mtl_buf(&mut BufReader::new(f)) {
                Ok((mats, _)) => materials.extend(mats),
                Err(e) => warnings.push(format!(
                    "{}: cannot parse MTL ({e}); parts keep their names, default materials",
                    p.display()
                )),
            },
            Err(_) => warnings
                .push(format!("{}: MTL file not found; parts keep their usemtl names, default materials", p.display())),
        }
    }
    for name in &usemtl {
        if !materials.iter().any(|m| &m.name == name) {
            materials.push(tobj::Material { name: name.clone(), ..Default::default() });
        }
    }
    let source =
        if mtllibs.is_empty() && !usemtl.is_empty() { format!("mtllib __psc_synthetic.mtl\n{text}") } else { text };
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let mats_for_loader = materials.clone();
    // (A synthetic mtllib line adds a few bytes beyond the file's size to the count.)
    let mut reader = BufReader::new(Counting { inner: source.as_bytes(), progress });
    let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Ok((mats_for_loader.clone(), mats_for_loader.iter().enumerate().map(|(i, m)| (m.name.clone(), i)).collect()))
    })
    .map_err(|e| RenderError::Obj { path: path.to_path_buf(), message: e.to_string() })?;

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

/// Load an emitter mesh: triangles whose winding gives the emitting side. When the OBJ has
/// vertex normals and they disagree with the winding, the winding is flipped to follow them.
pub fn load_emitter(path: &Path, warnings: &mut Vec<String>) -> Result<Vec<[Vec3; 3]>, RenderError> {
    let mut local = Vec::new();
    let mesh = load_obj(path, &mut local)?;
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
