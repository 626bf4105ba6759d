//! G-buffers: per pixel, what the camera ray through the pixel centre hits.
//!
//! Conventions: `part_id` 0 = nothing, 1..=P = model part (index + 1 into the part names),
//! P+1.. = emitter (light index + P + 1). uv = mesh uv (OBJ convention, no uv transform).
//! Normals, tangent and bitangent are world-space unit vectors on the side facing the camera
//! (surfaces are two-sided); the shading normal includes the material's normal map when
//! materials are given. depth = distance from the camera centre along the ray (Mitsuba's `aov`
//! depth). Pixels without a model hit hold zeros.

use std::path::Path;

use psc_base::output::{Replace, StagedDir};
use rayon::prelude::*;
use serde::Serialize;

use crate::camera::Camera;
use crate::geometry::{SceneGeometry, Traced};
use crate::image_io;
use crate::material::MaterialBinding;
use crate::RenderError;

#[derive(Clone, Debug)]
pub struct GBuffer {
    pub width: usize,
    pub height: usize,
    pub part_id: Vec<u16>,
    pub uv: Vec<[f32; 2]>,
    pub normal_geometric: Vec<[f32; 3]>,
    pub normal_shading: Vec<[f32; 3]>,
    pub tangent: Vec<[f32; 3]>,
    pub bitangent: Vec<[f32; 3]>,
    pub depth: Vec<f32>,
    pub position: Vec<[f32; 3]>,
    /// Names for part ids 1..: model parts then lights.
    pub id_names: Vec<String>,
}

#[derive(Default, Clone, Copy)]
struct Px {
    id: u16,
    uv: [f32; 2],
    ng: [f32; 3],
    ns: [f32; 3],
    t: [f32; 3],
    b: [f32; 3],
    depth: f32,
    p: [f32; 3],
}

/// Memory a G-buffer needs per pixel: the traced pixel (88 bytes), the output arrays (80) and
/// one EXR being encoded (~24).
const BYTES_PER_PIXEL: u64 = 192;

/// G-buffer of `camera` at its resolution. `materials` (one per part) adds normal maps to the
/// shading normal; without them the shading normal is the interpolated mesh normal.
pub fn render_gbuffer(
    geometry: &SceneGeometry,
    camera: &Camera,
    part_names: &[String],
    light_names: &[String],
    materials: Option<&[MaterialBinding]>,
) -> Result<GBuffer, RenderError> {
    let (w, h) = (camera.width, camera.height);
    psc_base::limits::check_image("G-buffer", w as u64, h as u64, BYTES_PER_PIXEL)?;
    let n_parts = part_names.len() as u32;
    let px: Vec<Px> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let d = camera.direction(x as f32 + 0.5, y as f32 + 0.5);
            match geometry.trace(camera.position, d, f32::INFINITY) {
                Traced::Miss => Px::default(),
                Traced::Emitter { light, n, t } => {
                    let nn = if n.dot(d) < 0.0 { n } else { -n };
                    let p = camera.position + d * t;
                    Px {
                        id: (n_parts + 1 + light) as u16,
                        ng: nn.to_array(),
                        ns: nn.to_array(),
                        depth: t,
                        p: p.to_array(),
                        ..Default::default()
                    }
                }
                Traced::Surface(hit) => {
                    let tn = materials.map_or([0.0, 0.0, 1.0], |m| m[hit.part as usize].eval(hit.uv).normal);
                    let sf = geometry.shading_frame(&hit, -d, tn);
                    Px {
                        id: (hit.part + 1) as u16,
                        uv: hit.uv,
                        ng: sf.ng.to_array(),
                        ns: sf.frame.n.to_array(),
                        t: sf.tangent.to_array(),
                        b: sf.bitangent.to_array(),
                        depth: hit.t,
                        p: hit.p.to_array(),
                    }
                }
            }
        })
        .collect();
    let mut id_names: Vec<String> = part_names.to_vec();
    id_names.extend(light_names.iter().map(|n| format!("light:{n}")));
    Ok(GBuffer {
        width: w,
        height: h,
        part_id: px.iter().map(|p| p.id).collect(),
        uv: px.iter().map(|p| p.uv).collect(),
        normal_geometric: px.iter().map(|p| p.ng).collect(),
        normal_shading: px.iter().map(|p| p.ns).collect(),
        tangent: px.iter().map(|p| p.t).collect(),
        bitangent: px.iter().map(|p| p.b).collect(),
        depth: px.iter().map(|p| p.depth).collect(),
        position: px.iter().map(|p| p.p).collect(),
        id_names,
    })
}

#[derive(Serialize)]
struct GBufferIndex<'a> {
    format: &'static str,
    width: usize,
    height: usize,
    part_ids: std::collections::BTreeMap<u16, &'a str>,
    files: std::collections::BTreeMap<&'static str, &'static str>,
}

impl GBuffer {
    /// Write `dir/part_id.png` (16-bit), `uv.exr` (u, v, 0), `normal_geometric.exr`,
    /// `normal_shading.exr`, `tangent.exr`, `bitangent.exr`, `position.exr`, `depth.exr`
    /// (depth in all three channels) and `gbuffer.json` (id → name, file list).
    /// The folder must exist; [`GBuffer::write_folder`] makes a new folder whole.
    pub fn save(&self, dir: &Path) -> Result<(), RenderError> {
        let (w, h) = (self.width, self.height);
        image_io::write_gray16(&dir.join("part_id.png"), w, h, &self.part_id)?;
        let uv: Vec<[f32; 3]> = self.uv.iter().map(|u| [u[0], u[1], 0.0]).collect();
        image_io::write_rgb(&dir.join("uv.exr"), w, h, &uv)?;
        image_io::write_rgb(&dir.join("normal_geometric.exr"), w, h, &self.normal_geometric)?;
        image_io::write_rgb(&dir.join("normal_shading.exr"), w, h, &self.normal_shading)?;
        image_io::write_rgb(&dir.join("tangent.exr"), w, h, &self.tangent)?;
        image_io::write_rgb(&dir.join("bitangent.exr"), w, h, &self.bitangent)?;
        image_io::write_rgb(&dir.join("position.exr"), w, h, &self.position)?;
        let depth: Vec<[f32; 3]> = self.depth.iter().map(|&d| [d; 3]).collect();
        image_io::write_rgb(&dir.join("depth.exr"), w, h, &depth)?;
        let index = GBufferIndex {
            format: "photoscene-gbuffer/1",
            width: w,
            height: h,
            part_ids: self.id_names.iter().enumerate().map(|(i, n)| ((i + 1) as u16, n.as_str())).collect(),
            files: [
                ("part_id", "part_id.png: 16-bit gray, 0 = nothing"),
                ("uv", "uv.exr: R = u, G = v (OBJ convention, v up)"),
                ("normal_geometric", "normal_geometric.exr: face normal facing the camera"),
                ("normal_shading", "normal_shading.exr: shading normal facing the camera"),
                ("tangent", "tangent.exr: unit dp/du orthogonal to the shading normal"),
                ("bitangent", "bitangent.exr: unit, sign of dp/dv"),
                ("position", "position.exr: world position"),
                ("depth", "depth.exr: distance from the camera centre, all channels"),
            ]
            .into_iter()
            .collect(),
        };
        let json = serde_json::to_vec_pretty(&index).map_err(|e| RenderError::Invalid(e.to_string()))?;
        image_io::atomic_write(&dir.join("gbuffer.json"), &json)
    }
}

impl GBuffer {
    /// Write the G-buffer files (see [`GBuffer::save`]) as the new folder `dest`, which appears
    /// whole or not at all; an existing `dest` is refused unless `replace` is `Replace::Yes`.
    pub fn write_folder(&self, dest: &Path, replace: Replace) -> Result<(), RenderError> {
        let staged = StagedDir::new(dest, replace)?;
        self.save(staged.path())?;
        staged.commit()?;
        Ok(())
    }
}

/// Fraction of labelled pixels (label ≠ 0 with a name in `part_labels`) whose G-buffer part has
/// that name. Returns (agreeing, labelled).
pub fn label_agreement(
    gb: &GBuffer,
    labels: &[u16],
    part_labels: &std::collections::BTreeMap<u16, String>,
) -> (usize, usize) {
    let mut agree = 0;
    let mut total = 0;
    for (i, &l) in labels.iter().enumerate() {
        let Some(name) = part_labels.get(&l) else { continue };
        total += 1;
        let id = gb.part_id[i] as usize;
        if id > 0 && gb.id_names.get(id - 1) == Some(name) {
            agree += 1;
        }
    }
    (agree, total)
}
