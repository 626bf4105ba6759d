//! What both formats share: per part, the triangles with their vertex attributes as the
//! renderer shades them (normals, the uv transform applied, tangent frames), the baked maps of
//! its material, and the light meshes with their radiances.
//!
//! Texture coordinates: the part's uv transform `(s, t) = M (u, v, 1)` is applied to every
//! vertex (exact: the map is affine and uvs interpolate linearly), then written in the
//! top-left-origin convention of glTF and Mitsuba's PLY loader, `(s, 1 − t)`, so that texture
//! row 0 (`t` near 1 in the renderer's v-up convention) is the image's top row in both.
//!
//! Tangents follow the renderer (`render/src/geometry.rs`, `MaterialBinding::eval`): the frame
//! is `t` along dp/du of the *mesh* uv orthogonalised against the normal, `b = σ n × t` with σ
//! the sign of dp/dv, and the material's tangent-space normal is rotated by the uv transform's
//! rotation θ before it is applied. The same normal in texture space is therefore applied with
//! the tangent `T' = cos θ t − sin θ b` and bitangent `σ n × T'`: `T'` is what the TANGENT
//! attribute holds (w = σ). For uv transforms with a uniform scale, `T'` is also the direction
//! of dp/ds of the transformed uv, which is what importers that derive tangents from
//! TEXCOORD_0 (MikkTSpace in Blender, `dp_du` in Mitsuba) use.
//!
//! Vertices: a mesh with vertex normals keeps its vertices (one exported vertex per mesh vertex
//! a part uses). A mesh without them is flat-shaded by the renderer; such vertices are split by
//! face normal (vertices of coplanar triangles stay shared), so each exported vertex carries
//! its face's normal exactly.

use std::collections::BTreeMap;

use glam::Vec3;
use psc_render::brdf::Frame;
use psc_render::material::MaterialBinding;
use psc_render::scene::Scene;
use psc_runtime::assign::{AssignError, Assignment, PartMaterial};
use psc_runtime::bake;
use psc_runtime::library::Library;

use crate::ExportError;

/// Vertex data of one part, ready for a vertex buffer.
#[derive(Clone, Debug, Default)]
pub struct PartMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// `(s, 1 − t)` of the transformed uv (see the module docs).
    pub texcoords: Vec<[f32; 2]>,
    /// `[T'x, T'y, T'z, σ]` (see the module docs).
    pub tangents: Vec<[f32; 4]>,
    /// Three vertex indices per triangle, in the mesh's winding.
    pub indices: Vec<u32>,
}

/// Baked maps of one part at `size`², row 0 at the top, ready to encode as PNG.
#[derive(Clone, Debug)]
pub struct BakedMaps {
    pub size: usize,
    /// sRGB bytes of albedo × albedo_scale, RGB.
    pub base_color: Vec<u8>,
    /// OpenGL-convention tangent-space normals (`(n + 1) / 2`), RGB; `None` when the graph's
    /// normal is `[0, 0, 1]` everywhere.
    pub normal: Option<Vec<u8>>,
    /// Roughness × roughness_scale clamped to [0, 1], linear bytes (one channel).
    pub roughness: Vec<u8>,
}

/// How a part looks.
#[derive(Clone, Debug)]
pub enum PartLook {
    /// A library graph, baked.
    Baked { graph: String, maps: BakedMaps },
    /// A part the assignment does not name keeps the scene's MTL colour and roughness
    /// (textures of the MTL are not carried over; the summary warns).
    Constant { albedo: [f32; 3], roughness: f32 },
}

/// One part of the scene, prepared.
#[derive(Clone, Debug)]
pub struct PreparedPart {
    pub name: String,
    /// Index-prefixed, file-name-safe name (`03_floor`): unique among the parts.
    pub stem: String,
    pub mesh: PartMesh,
    pub look: PartLook,
    /// Vertices whose tangent frame is left-handed (σ = −1) and right-handed: Mitsuba's
    /// normalmap always builds a right-handed frame, so a mostly left-handed part gets a map
    /// with the green channel inverted there.
    pub left_handed: usize,
    pub right_handed: usize,
}

/// One light, prepared: one-sided triangles emitting along their winding normal.
#[derive(Clone, Debug)]
pub struct PreparedLight {
    pub name: String,
    pub stem: String,
    pub mesh: PartMesh,
    pub radiance: [f32; 3],
}

/// Everything both writers need.
pub struct Prepared {
    pub parts: Vec<PreparedPart>,
    pub lights: Vec<PreparedLight>,
    pub warnings: Vec<String>,
}

/// `name` reduced to `[A-Za-z0-9_-]`, prefixed with its index so that stems are unique.
pub fn stem(index: usize, name: &str) -> String {
    let safe: String = name
        .chars()
        .take(48)
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
        .collect();
    format!("{index:02}_{safe}")
}

/// Checks the inputs (every assigned part exists, every graph and parameter binds, one finite
/// non-negative radiance per light) before anything is baked or written.
pub fn check_inputs(
    scene: &Scene,
    library: &Library,
    assignment: &Assignment,
    lights: &psc_render::LightRadiances,
) -> Result<(), ExportError> {
    let names = &scene.mesh.part_names;
    // `bind` checks parts, graphs and parameters together, with the assignment's own messages.
    let mut scratch: Vec<MaterialBinding> = names.iter().map(|_| MaterialBinding::constant([0.5; 3], 0.5)).collect();
    assignment.bind(library, names, &mut scratch).map_err(|e| ExportError::Input(e.to_string()))?;
    let light_names: Vec<String> = scene.lights.iter().map(|l| l.name.clone()).collect();
    lights.validate(&light_names).map_err(|e| ExportError::Input(e.to_string()))?;
    Ok(())
}

/// Prepares every part and light (bakes the assigned graphs at `texture_size`).
pub fn prepare(
    scene: &Scene,
    library: &Library,
    assignment: &Assignment,
    lights: &psc_render::LightRadiances,
    texture_size: usize,
) -> Result<Prepared, ExportError> {
    check_inputs(scene, library, assignment, lights)?;
    let mut warnings = Vec::new();
    let mesh = &scene.mesh;
    let mut parts = Vec::new();
    for (index, name) in mesh.part_names.iter().enumerate() {
        let tris: Vec<usize> = (0..mesh.triangles.len()).filter(|&k| mesh.tri_part[k] as usize == index).collect();
        if tris.is_empty() {
            warnings.push(format!("part '{name}' has no triangles; not exported"));
            continue;
        }
        let assigned = assignment.parts.get(name);
        let uv_matrix = assigned.map_or(psc_render::material::IDENTITY_UV, |p| p.uv.matrix());
        let (part_mesh, left, right) = part_mesh(scene, &tris, uv_matrix);
        let look = match assigned {
            Some(p) => PartLook::Baked { graph: p.graph.clone(), maps: bake_part(name, p, library, texture_size)? },
            None => {
                let info = mesh.part_mtl.get(index).cloned().unwrap_or_default();
                if info.map_kd.is_some() {
                    warnings.push(format!(
                        "part '{name}' is not in the assignment: exported with its MTL colour Kd, without its texture"
                    ));
                }
                PartLook::Constant { albedo: info.kd.unwrap_or([0.5; 3]), roughness: info.roughness.unwrap_or(0.5) }
            }
        };
        parts.push(PreparedPart {
            name: name.clone(),
            stem: stem(index, name),
            mesh: part_mesh,
            look,
            left_handed: left,
            right_handed: right,
        });
    }
    let prepared_lights = scene
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| PreparedLight {
            name: l.name.clone(),
            stem: stem(i, &l.name),
            mesh: light_mesh(&l.triangles),
            radiance: lights.lights[i],
        })
        .collect();
    if scene.environment.is_some() {
        warnings.push("the scene's environment map is not exported (only its lights and parts are)".into());
    }
    Ok(Prepared { parts, lights: prepared_lights, warnings })
}

/// Bakes the part's graph and applies its albedo and roughness scales as the renderer does
/// (`MaterialBinding::eval`: albedo ≥ 0, NaN → 0; roughness clamped to [0, 1], NaN → 1).
fn bake_part(name: &str, part: &PartMaterial, library: &Library, size: usize) -> Result<BakedMaps, ExportError> {
    let (material, params) = part.resolve(library).map_err(|problem| {
        let located = AssignError { file: None, part: Some(name.to_string()), field: None, problem: Box::new(problem) };
        ExportError::Input(located.to_string())
    })?;
    let eval = |p: &[f32], u: &[f32], v: &[f32]| material.kernel.eval(p, u, v).map_err(|e| e.to_string());
    let maps = bake::bake(&eval, &params, size)
        .map_err(|e| ExportError::Input(format!("baking graph `{}`: {e}", part.graph)))?;
    let byte = |x: f32| if x.is_nan() { 0 } else { (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8 };
    let base_color = maps
        .albedo
        .chunks_exact(3)
        .flat_map(|c| {
            (0..3).map(move |k| {
                let a = c[k] * part.albedo_scale[k];
                let a = if a.is_finite() { a.max(0.0) } else { 0.0 };
                byte(bake::linear_to_srgb(a))
            })
        })
        .collect();
    let roughness = maps
        .roughness
        .iter()
        .map(|&r| {
            let r = r * part.roughness_scale;
            byte(if r.is_finite() { r.clamp(0.0, 1.0) } else { 1.0 })
        })
        .collect();
    let flat = maps.normal.chunks_exact(3).all(|n| n[0].abs() < 1e-3 && n[1].abs() < 1e-3 && n[2] > 0.0);
    let normal = (!flat).then(|| maps.normal.iter().map(|&x| byte(x * 0.5 + 0.5)).collect());
    Ok(BakedMaps { size, base_color, normal, roughness })
}

/// dp/du and dp/dv of a triangle in the mesh uv, as the renderer computes them (a frame around
/// the face normal when the uvs are degenerate).
fn triangle_derivatives(p: [Vec3; 3], uv: [[f32; 2]; 3], ng: Vec3) -> (Vec3, Vec3) {
    let (d02, d12) = (p[0] - p[2], p[1] - p[2]);
    let (a, b) = ([uv[0][0] - uv[2][0], uv[0][1] - uv[2][1]], [uv[1][0] - uv[2][0], uv[1][1] - uv[2][1]]);
    let det = a[0] * b[1] - a[1] * b[0];
    if det.abs() > 1e-12 {
        let inv = 1.0 / det;
        ((d02 * b[1] - d12 * a[1]) * inv, (d12 * a[0] - d02 * b[0]) * inv)
    } else {
        let f = Frame::from_normal(ng);
        (f.t, f.b)
    }
}

/// The vertices, attributes and indices of the triangles `tris` (see the module docs); also
/// the counts of left- and right-handed tangent frames.
fn part_mesh(scene: &Scene, tris: &[usize], uv_matrix: [[f32; 3]; 2]) -> (PartMesh, usize, usize) {
    let mesh = &scene.mesh;
    let binding = MaterialBinding::constant([0.5; 3], 0.5).with_uv_transform(uv_matrix);
    let (cos, sin) = binding.uv_rotation();
    let smooth = !mesh.normals.is_empty();
    // Exported vertex per (mesh vertex, face normal bits when flat).
    let mut index_of: BTreeMap<(u32, [u32; 3]), u32> = BTreeMap::new();
    let mut out = PartMesh::default();
    let mut derivs: Vec<(Vec3, Vec3)> = Vec::new();
    for &k in tris {
        let tri = mesh.triangles[k];
        let p = tri.map(|i| mesh.positions[i as usize]);
        let uv = tri.map(|i| mesh.uvs[i as usize]);
        let ng = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        let (dpdu, dpdv) = triangle_derivatives(p, uv, ng);
        for (corner, &vi) in tri.iter().enumerate() {
            let n = if smooth { mesh.normals[vi as usize].try_normalize().unwrap_or(ng) } else { ng };
            let key = (vi, if smooth { [0; 3] } else { ng.to_array().map(f32::to_bits) });
            let next = out.positions.len() as u32;
            let e = *index_of.entry(key).or_insert(next);
            if e == next {
                let [u, v] = uv[corner];
                let s = binding.transform_uv([u, v]);
                out.positions.push(p[corner].to_array());
                out.normals.push(n.to_array());
                out.texcoords.push([s[0], 1.0 - s[1]]);
                derivs.push((Vec3::ZERO, Vec3::ZERO));
            }
            derivs[e as usize].0 += dpdu;
            derivs[e as usize].1 += dpdv;
            out.indices.push(e);
        }
    }
    let (mut left, mut right) = (0, 0);
    for (i, (dpdu, dpdv)) in derivs.into_iter().enumerate() {
        let n = Vec3::from(out.normals[i]);
        let n = if n.length_squared() > 0.0 { n } else { Vec3::Y };
        let base = Frame::new(n, dpdu);
        let sigma = if base.b.dot(dpdv) < 0.0 { -1.0 } else { 1.0 };
        let b = base.b * sigma;
        let t = (base.t * cos - b * sin).normalize_or(base.t);
        if sigma < 0.0 {
            left += 1;
        } else {
            right += 1;
        }
        out.tangents.push([t.x, t.y, t.z, sigma]);
        if out.normals[i] == [0.0; 3] {
            // A degenerate triangle alone at a vertex: any unit normal keeps the file valid.
            out.normals[i] = n.to_array();
        }
    }
    (out, left, right)
}

/// A light's triangles as a mesh: three vertices each, the winding normal at each.
fn light_mesh(triangles: &[[Vec3; 3]]) -> PartMesh {
    let mut out = PartMesh::default();
    for t in triangles {
        let n = (t[1] - t[0]).cross(t[2] - t[0]).try_normalize().unwrap_or(Vec3::Y);
        for p in t {
            out.indices.push(out.positions.len() as u32);
            out.positions.push(p.to_array());
            out.normals.push(n.to_array());
            out.texcoords.push([0.0, 0.0]);
            let f = Frame::from_normal(n);
            out.tangents.push([f.t.x, f.t.y, f.t.z, 1.0]);
        }
    }
    out
}
