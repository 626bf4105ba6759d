//! `scene_mitsuba.xml` + `meshes/*.ply`: the room as a Mitsuba 3 scene that renders the input
//! views (`mitsuba -s i -o view.exr scene_mitsuba.xml` renders view i, in the order of
//! scene.json; from Python `mi.render(mi.load_file(…), sensor=i)`).
//!
//! - Per part a binary PLY (positions, normals, uv as [`crate::prepare`] makes them) and the
//!   BSDF closest to the renderer's Karis model (`render/src/brdf.rs`: Lambert + GGX, Schlick
//!   F0 = 0.05, α = r²) that Mitsuba has natively: `principled` with the baked base colour and
//!   roughness bitmaps (Mitsuba's principled also takes α = roughness²), `specular` 0.625
//!   (its F0 = 0.08 × specular = 0.05), `metallic` 0; wrapped in `normalmap` where the graph
//!   perturbs normals and in `twosided`, as the renderer shades both sides. Principled's
//!   diffuse lobe is Disney's (retro-reflection at grazing angles), not Lambert: that, and
//!   8-bit maps, are the differences left.
//! - Mitsuba's normalmap builds its frame from dp/du of the PLY's uv and a right-handed
//!   bitangent; on parts whose frame is left-handed the map with green inverted is used.
//! - Lights: a PLY per light with an `area` emitter of the given radiance (one-sided, along the
//!   winding normal, as the renderer's) and a black diffuse BSDF.
//! - One `perspective` sensor per view (id = view name, vertical fov, `lookat`, the photo's
//!   size, box filter), the conventions of `tools/mitsuba_check.py`; a `path` integrator with
//!   `max_depth` 6 (the renderer's default). `$spp` (default 64) and `$max_depth` can be set
//!   with `mitsuba -D spp=256`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use psc_render::scene::Scene;

use crate::prepare::{PartLook, PartMesh, Prepared};
use crate::{mitsuba_flips_normal, write_file, ExportError, TextureNames};

/// Mitsuba's principled `specular` for the renderer's F0 (F0 = 0.08 × specular).
pub const PRINCIPLED_SPECULAR: f32 = psc_render::brdf::F0 / 0.08;

/// XML-escaped attribute text.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;").replace('\'', "&apos;")
}

fn vec3(v: [f32; 3]) -> String {
    format!("{}, {}, {}", v[0], v[1], v[2])
}

/// A binary little-endian PLY: float x y z nx ny nz u v, int triangles.
pub fn ply_bytes(m: &PartMesh) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment photoscene psc-export\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float u\nproperty float v\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.indices.len() / 3
    )
    .into_bytes();
    for i in 0..m.positions.len() {
        for x in m.positions[i].iter().chain(&m.normals[i]).chain(&m.texcoords[i]) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    for t in m.indices.chunks_exact(3) {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}

fn bitmap(name: &str, file: &str, raw: bool) -> String {
    format!(
        "<texture type=\"bitmap\" name=\"{name}\"><string name=\"filename\" value=\"{}\"/>\
         <boolean name=\"raw\" value=\"{raw}\"/><string name=\"filter_type\" value=\"bilinear\"/>\
         <string name=\"wrap_mode\" value=\"repeat\"/></texture>",
        esc(file)
    )
}

/// Writes `scene_mitsuba.xml` and `meshes/*.ply` into `dir` (the textures are already there);
/// returns the files written.
pub fn write(dir: &Path, scene: &Scene, prepared: &Prepared) -> Result<Vec<PathBuf>, ExportError> {
    let mut files = Vec::new();
    let mut x = String::new();
    let _ = writeln!(x, "<?xml version=\"1.0\" encoding=\"utf-8\"?>");
    let _ =
        writeln!(x, "<!-- photoscene psc-export: the fitted room for Mitsuba 3, one sensor per view of scene.json.");
    let _ = writeln!(x, "     Render view i: mitsuba -s i -D spp=256 -o view.exr scene_mitsuba.xml");
    let _ = writeln!(x, "     (Python: mi.render(mi.load_file('scene_mitsuba.xml', spp='256'), sensor=i)). -->");
    let _ = writeln!(x, "<scene version=\"3.0.0\">");
    let _ = writeln!(x, "  <default name=\"spp\" value=\"64\"/>");
    let _ = writeln!(x, "  <default name=\"max_depth\" value=\"6\"/>");
    let _ = writeln!(x, "  <integrator type=\"path\"><integer name=\"max_depth\" value=\"$max_depth\"/></integrator>");
    for view in &scene.views {
        let c = &view.camera_spec;
        let _ = writeln!(
            x,
            "  <sensor type=\"perspective\" id=\"{}\">\n    <string name=\"fov_axis\" value=\"y\"/>\
             <float name=\"fov\" value=\"{}\"/><float name=\"near_clip\" value=\"0.01\"/>\n    \
             <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform>\n    \
             <sampler type=\"independent\"><integer name=\"sample_count\" value=\"$spp\"/></sampler>\n    \
             <film type=\"hdrfilm\"><integer name=\"width\" value=\"{}\"/><integer name=\"height\" value=\"{}\"/>\
             <rfilter type=\"box\"/><string name=\"pixel_format\" value=\"rgb\"/></film>\n  </sensor>",
            esc(&view.name),
            c.fov_y_deg,
            vec3(c.position),
            vec3(c.look_at),
            vec3(c.up),
            view.width,
            view.height
        );
    }
    for part in &prepared.parts {
        let ply = format!("meshes/{}.ply", part.stem);
        files.push(write_file(dir, &ply, &ply_bytes(&part.mesh))?);
        let principled = match &part.look {
            PartLook::Baked { maps, .. } => {
                let names = TextureNames::of(&part.stem);
                let inner = format!(
                    "<bsdf type=\"principled\">{}{}<float name=\"specular\" value=\"{PRINCIPLED_SPECULAR}\"/>\
                     <float name=\"metallic\" value=\"0\"/></bsdf>",
                    bitmap("base_color", &names.base_color, false),
                    bitmap("roughness", &names.roughness, true)
                );
                match maps.normal {
                    Some(_) => {
                        let file = if mitsuba_flips_normal(part) { &names.normal_flipped } else { &names.normal };
                        format!("<bsdf type=\"normalmap\">{}{inner}</bsdf>", bitmap("normalmap", file, true))
                    }
                    None => inner,
                }
            }
            PartLook::Constant { albedo, roughness } => format!(
                "<bsdf type=\"principled\"><rgb name=\"base_color\" value=\"{}\"/>\
                 <float name=\"roughness\" value=\"{}\"/><float name=\"specular\" value=\"{PRINCIPLED_SPECULAR}\"/>\
                 <float name=\"metallic\" value=\"0\"/></bsdf>",
                vec3(albedo.map(|a| a.clamp(0.0, 1.0))),
                roughness.clamp(0.0, 1.0)
            ),
        };
        let _ = writeln!(
            x,
            "  <shape type=\"ply\" id=\"part:{}\">\n    <string name=\"filename\" value=\"{}\"/>\n    \
             <bsdf type=\"twosided\">{principled}</bsdf>\n  </shape>",
            esc(&part.name),
            esc(&ply)
        );
    }
    for light in &prepared.lights {
        let ply = format!("meshes/light_{}.ply", light.stem);
        files.push(write_file(dir, &ply, &ply_bytes(&light.mesh))?);
        let _ = writeln!(
            x,
            "  <shape type=\"ply\" id=\"light:{}\">\n    <string name=\"filename\" value=\"{}\"/>\n    \
             <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0\"/></bsdf>\n    \
             <emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter>\n  </shape>",
            esc(&light.name),
            esc(&ply),
            vec3(light.radiance)
        );
    }
    let _ = writeln!(x, "</scene>");
    files.push(write_file(dir, "scene_mitsuba.xml", x.as_bytes())?);
    Ok(files)
}
