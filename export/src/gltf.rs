//! `scene.gltf` + `scene.bin`: glTF 2.0, metallic-roughness, built as typed `gltf-json`
//! structs and serialised by serde (no hand-written JSON).
//!
//! - One mesh (one triangle primitive) and one node per part: POSITION, NORMAL, TEXCOORD_0
//!   (the uv transform baked in, textures REPEAT: see [`crate::prepare`]), TANGENT where a
//!   normal map is used; a material with the baked base colour, the packed
//!   metallic-roughness map (G = roughness, B = metallic = 0: the renderer's Karis BRDF is a
//!   dielectric) and the normal map; double-sided, as the renderer shades both sides. The
//!   renderer's F0 is 0.05 where glTF's dielectric is 0.04, so `KHR_materials_specular` scales
//!   the specular colour by 1.25. Parts without an assigned graph get the MTL colour as factors.
//! - Lights: one mesh per light, emissive, with `emissiveFactor` the colour normalised by its
//!   largest channel and `KHR_materials_emissive_strength` that channel's radiance, so
//!   factor × strength is the radiance in W m⁻² sr⁻¹; single-sided (the lights emit along their
//!   winding normal only) and black otherwise.
//! - One camera node per scene view (vertical field of view, the photo's aspect ratio).
//! - Units are metres; a root node rotates the scene's `up` onto glTF's +Y when they differ.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Quat, Vec3};
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use json::{accessor, buffer, camera, material, mesh, scene, texture, Index};
use psc_render::scene::Scene;

use crate::prepare::{PartLook, PartMesh, Prepared};
use crate::{write_file, ExportError, TextureNames};

/// The renderer's dielectric F0 over glTF's 0.04 (`psc_render::brdf::F0`).
pub const SPECULAR_COLOR_SCALE: f32 = psc_render::brdf::F0 / 0.04;

/// The binary buffer being built and the views and accessors into it.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
}

impl Builder {
    /// A view over `bytes` (4-byte aligned in the buffer).
    fn view(&mut self, bytes: &[u8], stride: Option<usize>, target: buffer::Target) -> Index<buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(buffer::View {
            buffer: Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: stride.map(buffer::Stride),
            name: None,
            target: Some(Valid(target)),
            extensions: None,
            extras: Default::default(),
        })
    }

    /// A float vertex attribute of `N` components.
    fn attribute<const N: usize>(&mut self, data: &[[f32; N]], with_bounds: bool) -> Index<accessor::Accessor> {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(4 * N), buffer::Target::ArrayBuffer);
        let (min, max) = if with_bounds {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in data {
                for k in 0..N {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            (Some(serde_json::json!(lo.to_vec())), Some(serde_json::json!(hi.to_vec())))
        } else {
            (None, None)
        };
        let type_ = match N {
            2 => accessor::Type::Vec2,
            3 => accessor::Type::Vec3,
            _ => accessor::Type::Vec4,
        };
        self.accessor(view, data.len(), accessor::ComponentType::F32, type_, min, max)
    }

    fn indices(&mut self, indices: &[u32]) -> Index<accessor::Accessor> {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, None, buffer::Target::ElementArrayBuffer);
        self.accessor(view, indices.len(), accessor::ComponentType::U32, accessor::Type::Scalar, None, None)
    }

    fn accessor(
        &mut self,
        view: Index<buffer::View>,
        count: usize,
        component: accessor::ComponentType,
        type_: accessor::Type,
        min: Option<serde_json::Value>,
        max: Option<serde_json::Value>,
    ) -> Index<accessor::Accessor> {
        self.root.push(accessor::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Valid(accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A triangle primitive of `mesh` (tangents only when asked for).
    fn primitive(&mut self, m: &PartMesh, tangents: bool, material: Index<material::Material>) -> mesh::Primitive {
        let mut attributes = BTreeMap::new();
        attributes.insert(Valid(mesh::Semantic::Positions), self.attribute(&m.positions, true));
        attributes.insert(Valid(mesh::Semantic::Normals), self.attribute(&m.normals, false));
        attributes.insert(Valid(mesh::Semantic::TexCoords(0)), self.attribute(&m.texcoords, false));
        if tangents {
            attributes.insert(Valid(mesh::Semantic::Tangents), self.attribute(&m.tangents, false));
        }
        mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(self.indices(&m.indices)),
            material: Some(material),
            mode: Valid(mesh::Mode::Triangles),
            targets: None,
        }
    }

    fn texture(&mut self, uri: &str, sampler: Index<texture::Sampler>) -> texture::Info {
        let image = self.root.push(json::Image {
            buffer_view: None,
            mime_type: None,
            name: None,
            uri: Some(uri.to_string()),
            extensions: None,
            extras: Default::default(),
        });
        let index = self.root.push(texture::Texture {
            name: None,
            sampler: Some(sampler),
            source: image,
            extensions: None,
            extras: Default::default(),
        });
        texture::Info { index, tex_coord: 0, extensions: None, extras: Default::default() }
    }

    fn mesh_node(&mut self, name: &str, primitive: mesh::Primitive) -> Index<scene::Node> {
        let mesh = self.root.push(mesh::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(name.to_string()),
            primitives: vec![primitive],
            weights: None,
        });
        self.root.push(scene::Node { mesh: Some(mesh), name: Some(name.to_string()), ..Default::default() })
    }
}

fn specular_extension() -> json::extensions::material::Specular {
    json::extensions::material::Specular {
        specular_color_factor: json::extensions::material::SpecularColorFactor([SPECULAR_COLOR_SCALE; 3]),
        ..Default::default()
    }
}

/// Writes `scene.gltf` and `scene.bin` into `dir` (the textures are already there); returns the
/// files written.
pub fn write(dir: &Path, scene: &Scene, prepared: &Prepared) -> Result<Vec<PathBuf>, ExportError> {
    let mut b = Builder { root: json::Root::default(), bin: Vec::new() };
    b.root.asset = json::Asset {
        generator: Some(format!("photoscene psc-export {}", env!("CARGO_PKG_VERSION"))),
        version: "2.0".into(),
        ..Default::default()
    };
    let repeat = b.root.push(texture::Sampler {
        mag_filter: Some(Valid(texture::MagFilter::Linear)),
        min_filter: Some(Valid(texture::MinFilter::LinearMipmapLinear)),
        wrap_s: Valid(texture::WrappingMode::Repeat),
        wrap_t: Valid(texture::WrappingMode::Repeat),
        name: None,
        extensions: None,
        extras: Default::default(),
    });
    let mut children = Vec::new();
    let mut uses_specular = false;
    for part in &prepared.parts {
        let mut m = material::Material { name: Some(part.name.clone()), double_sided: true, ..Default::default() };
        m.pbr_metallic_roughness.metallic_factor = material::StrengthFactor(0.0);
        let mut tangents = false;
        match &part.look {
            PartLook::Baked { maps, .. } => {
                let names = TextureNames::of(&part.stem);
                m.pbr_metallic_roughness.base_color_texture = Some(b.texture(&names.base_color, repeat));
                // metallicFactor 1 × B (0) = 0: the packed map says it, as glTF viewers expect.
                m.pbr_metallic_roughness.metallic_factor = material::StrengthFactor(1.0);
                m.pbr_metallic_roughness.roughness_factor = material::StrengthFactor(1.0);
                m.pbr_metallic_roughness.metallic_roughness_texture =
                    Some(b.texture(&names.metallic_roughness, repeat));
                if maps.normal.is_some() {
                    let info = b.texture(&names.normal, repeat);
                    m.normal_texture = Some(material::NormalTexture {
                        index: info.index,
                        scale: 1.0,
                        tex_coord: 0,
                        extensions: None,
                        extras: Default::default(),
                    });
                    tangents = true;
                }
            }
            PartLook::Constant { albedo, roughness } => {
                let a = albedo.map(|x| if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 });
                m.pbr_metallic_roughness.base_color_factor = material::PbrBaseColorFactor([a[0], a[1], a[2], 1.0]);
                m.pbr_metallic_roughness.roughness_factor = material::StrengthFactor(roughness.clamp(0.0, 1.0));
            }
        }
        m.extensions =
            Some(json::extensions::material::Material { specular: Some(specular_extension()), ..Default::default() });
        uses_specular = true;
        let material = b.root.push(m);
        let primitive = b.primitive(&part.mesh, tangents, material);
        children.push(b.mesh_node(&part.name, primitive));
    }
    let mut uses_strength = false;
    for light in &prepared.lights {
        let peak = light.radiance.iter().copied().fold(0.0f32, f32::max);
        let mut m = material::Material { name: Some(format!("light:{}", light.name)), ..Default::default() };
        m.pbr_metallic_roughness.base_color_factor = material::PbrBaseColorFactor([0.0, 0.0, 0.0, 1.0]);
        m.pbr_metallic_roughness.metallic_factor = material::StrengthFactor(0.0);
        m.pbr_metallic_roughness.roughness_factor = material::StrengthFactor(1.0);
        if peak > 0.0 {
            m.emissive_factor = material::EmissiveFactor(light.radiance.map(|c| c / peak));
            if peak != 1.0 {
                uses_strength = true;
                m.extensions = Some(json::extensions::material::Material {
                    emissive_strength: Some(json::extensions::material::EmissiveStrength {
                        emissive_strength: json::extensions::material::EmissiveStrengthFactor(peak),
                    }),
                    ..Default::default()
                });
            }
        }
        let material = b.root.push(m);
        let primitive = b.primitive(&light.mesh, false, material);
        children.push(b.mesh_node(&format!("light:{}", light.name), primitive));
    }
    for view in &scene.views {
        let cam = &view.camera;
        let camera = b.root.push(camera::Camera {
            name: Some(view.name.clone()),
            orthographic: None,
            perspective: Some(camera::Perspective {
                aspect_ratio: Some(view.width as f32 / view.height as f32),
                yfov: view.camera_spec.fov_y_deg.to_radians(),
                zfar: None,
                znear: 0.01,
                extensions: None,
                extras: Default::default(),
            }),
            type_: Valid(camera::Type::Perspective),
            extensions: None,
            extras: Default::default(),
        });
        // glTF cameras look along their local −Z with +Y up and +X to the right.
        let basis = Mat3::from_cols(cam.right, cam.up, -cam.forward);
        let q = Quat::from_mat3(&basis).normalize();
        children.push(b.root.push(scene::Node {
            camera: Some(camera),
            name: Some(view.name.clone()),
            rotation: Some(scene::UnitQuaternion(q.to_array())),
            translation: Some(cam.position.to_array()),
            ..Default::default()
        }));
    }
    let to_y = Quat::from_rotation_arc(scene.up.normalize(), Vec3::Y);
    let root_node = b.root.push(scene::Node {
        children: Some(children),
        name: Some("photoscene".into()),
        rotation: (to_y.angle_between(Quat::IDENTITY) > 1e-6).then(|| scene::UnitQuaternion(to_y.to_array())),
        ..Default::default()
    });
    let s = b.root.push(scene::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some("photoscene".into()),
        nodes: vec![root_node],
    });
    b.root.scene = Some(s);
    if uses_specular {
        b.root.extensions_used.push("KHR_materials_specular".into());
    }
    if uses_strength {
        b.root.extensions_used.push("KHR_materials_emissive_strength".into());
    }
    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    b.root.push(json::Buffer {
        byte_length: USize64::from(b.bin.len()),
        name: None,
        uri: Some("scene.bin".into()),
        extensions: None,
        extras: Default::default(),
    });
    let mut text = b.root.to_string_pretty().map_err(|e| ExportError::io(&dir.join("scene.gltf"), e))?;
    text.push('\n');
    let bin = write_file(dir, "scene.bin", &b.bin)?;
    let gltf = write_file(dir, "scene.gltf", text.as_bytes())?;
    Ok(vec![bin, gltf])
}
