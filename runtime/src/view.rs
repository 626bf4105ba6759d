//! Opening a scene for one view: everything `psc render` (and the fit, and tests) need before
//! tracing a ray, from a description of what the user asked for ([`ViewRequest`]).
//!
//! - Geometry: the scene's coarse model, or the dev scenes' true geometry when asked for by name.
//! - Camera and resolution: a view of the scene (the first by default; its photo's size), or a
//!   camera file (its `width`/`height`, else the first view's size, else 640×480); an explicit
//!   size overrides either.
//! - Materials: the MTL's, or the dev scenes' true materials when asked for by name; then an
//!   assignment already in memory (a fit's materials, edited) and an assignment file bind
//!   library graphs to the parts they name, in that order.
//! - Light radiances ([`LightsSource`]): a lights file, or the true radiances when asked for by
//!   name, or by default every light and the environment at unit radiance (with a warning
//!   saying so).
//!
//! Ground truth is read only when a choice names it ([`GeometryChoice::Truth`],
//! [`MaterialsChoice::Truth`], [`LightsSource::Truth`]), through `psc_render::truth`.

use std::fmt;
use std::path::PathBuf;

use psc_base::progress::Progress;
use psc_render::camera::{load_camera_file, Camera};
use psc_render::material::MaterialBinding;
use psc_render::{truth, LightRadiances, LightsSource, RenderError, Scene};

use crate::assign::{AssignError, Assignment};
use crate::library::{default_library_root, Library, LibraryError};

/// Which mesh to trace.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum GeometryChoice {
    /// The scene's coarse model (`scene.json` "mesh").
    #[default]
    Model,
    /// `truth/scene_true.obj` (validation only).
    Truth,
}

/// Where the camera and the default resolution come from.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum CameraChoice {
    /// The first view of the scene.
    #[default]
    FirstView,
    /// The view with this name.
    View(String),
    /// A camera file (see `psc_render::camera::load_camera_file`).
    File(PathBuf),
}

/// The materials parts get before an assignment is applied.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum MaterialsChoice {
    /// From the MTL: `map_Kd` textures, else `Kd`; roughness `Pr`, else 0.5.
    #[default]
    Mtl,
    /// The dev scenes' `truth/truth.json` materials (validation only).
    Truth,
}

/// What to open. `Default` is the scene's first view with the model, MTL materials and unit
/// radiance; set `scene` and whatever else differs.
#[derive(Clone, Debug)]
pub struct ViewRequest {
    pub scene: PathBuf,
    pub geometry: GeometryChoice,
    pub camera: CameraChoice,
    /// Width × height, overriding the view's or the camera file's.
    pub size: Option<(usize, usize)>,
    pub materials: MaterialsChoice,
    /// An assignment in memory (a fit's `materials.json` with `--set` edits), bound before
    /// `assign`.
    pub assignment: Option<Assignment>,
    /// An assignment file binding library graphs to parts (see [`crate::assign`]).
    pub assign: Option<PathBuf>,
    /// The library for `assign` when the caller passes none (default: the shipped graphs/).
    pub library: Option<PathBuf>,
    /// The radiances: unit (said in a warning), a lights file, or the truth.
    pub lights: LightsSource,
}

/// A scene ready to render from one camera.
pub struct OpenedView {
    pub scene: Scene,
    pub camera: Camera,
    /// The scene view whose camera this is (None for a camera file).
    pub view: Option<String>,
    pub width: usize,
    pub height: usize,
    /// One binding per part, in the order of `scene.mesh.part_names`.
    pub materials: Vec<MaterialBinding>,
    pub radiances: LightRadiances,
    /// Everything the user should see: the scene's warnings, then those of materials and lights.
    pub warnings: Vec<String>,
}

impl Default for ViewRequest {
    fn default() -> Self {
        ViewRequest {
            scene: PathBuf::new(),
            geometry: GeometryChoice::Model,
            camera: CameraChoice::FirstView,
            size: None,
            materials: MaterialsChoice::Mtl,
            assignment: None,
            assign: None,
            library: None,
            lights: LightsSource::Default,
        }
    }
}

/// Why a view could not be opened.
#[derive(Debug)]
pub enum OpenError {
    Render(RenderError),
    Assign(AssignError),
    Library(LibraryError),
    /// A validation choice named ground truth the scene does not have.
    NoTruth {
        what: &'static str,
        scene: PathBuf,
    },
    NoSuchView {
        name: String,
        known: Vec<String>,
    },
    /// The scene has no views and no camera file was given.
    NoViews {
        scene: PathBuf,
    },
}

impl fmt::Display for OpenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OpenError::Render(e) => e.fmt(f),
            OpenError::Assign(e) => e.fmt(f),
            OpenError::Library(e) => e.fmt(f),
            OpenError::NoTruth { what, scene } => {
                write!(f, "{}: asked for the true {what}, but the scene has no ground truth for it", scene.display())
            }
            OpenError::NoSuchView { name, known } if known.is_empty() => {
                write!(f, "no view '{name}': the scene has no views")
            }
            OpenError::NoSuchView { name, known } => write!(f, "no view '{name}' (views: {})", known.join(", ")),
            OpenError::NoViews { scene } => {
                write!(f, "{}: the scene has no views; give a camera file", scene.display())
            }
        }
    }
}

impl std::error::Error for OpenError {}

impl From<RenderError> for OpenError {
    fn from(e: RenderError) -> Self {
        OpenError::Render(e)
    }
}

/// The default resolution when neither a view nor a camera file gives one.
pub const FALLBACK_SIZE: (usize, usize) = (640, 480);

/// Opens `req` (see the module docs). `library` serves the assignment when given; otherwise it
/// is loaded from `req.library` (or the shipped graphs/) only if there is an assignment.
/// Loading the meshes reports to `progress`.
pub fn open_view(
    req: &ViewRequest,
    library: Option<&Library>,
    progress: &dyn Progress,
) -> Result<OpenedView, OpenError> {
    let mesh_override = match req.geometry {
        GeometryChoice::Model => None,
        GeometryChoice::Truth => Some(
            truth::truth_mesh(&req.scene)
                .ok_or_else(|| OpenError::NoTruth { what: "geometry", scene: req.scene.clone() })?,
        ),
    };
    let scene = Scene::load_with_progress(&req.scene, mesh_override.as_deref(), progress)?;
    let mut warnings = scene.warnings.clone();

    let (spec, default_size, context, view) = match &req.camera {
        CameraChoice::File(path) => {
            let file = load_camera_file(path)?;
            let size = file.size.or_else(|| scene.views.first().map(|v| (v.width, v.height))).unwrap_or(FALLBACK_SIZE);
            (file.camera, size, path.display().to_string(), None)
        }
        choice => {
            let view = match choice {
                CameraChoice::View(name) => scene.view(name).ok_or_else(|| OpenError::NoSuchView {
                    name: name.clone(),
                    known: scene.views.iter().map(|v| v.name.clone()).collect(),
                })?,
                _ => scene.views.first().ok_or_else(|| OpenError::NoViews { scene: req.scene.clone() })?,
            };
            let context = format!("view '{}'", view.name);
            (view.camera_spec.clone(), (view.width, view.height), context, Some(view.name.clone()))
        }
    };
    let (width, height) = req.size.unwrap_or(default_size);
    let camera = Camera::new(&spec, width, height, &context)?;

    let mut materials = match req.materials {
        MaterialsChoice::Mtl => scene.mtl_materials(&mut warnings),
        MaterialsChoice::Truth => truth::truth_materials(&scene, &mut warnings)?,
    };
    if req.assign.is_some() || req.assignment.is_some() {
        // Read before compiling the library: a broken file fails fast.
        let from_file = match &req.assign {
            Some(path) => Some((Assignment::read(path).map_err(OpenError::Assign)?, path)),
            None => None,
        };
        let loaded;
        let library = match library {
            Some(l) => l,
            None => {
                let root = req.library.clone().unwrap_or_else(default_library_root);
                loaded = Library::load(&root).map_err(OpenError::Library)?;
                &loaded
            }
        };
        if let Some(assignment) = &req.assignment {
            assignment.bind(library, &scene.mesh.part_names, &mut materials).map_err(OpenError::Assign)?;
        }
        if let Some((assignment, path)) = from_file {
            assignment
                .bind(library, &scene.mesh.part_names, &mut materials)
                .map_err(|e| OpenError::Assign(e.in_file(path)))?;
        }
    }

    let radiances = LightRadiances::resolve(&scene, &req.lights, &mut warnings)?;
    Ok(OpenedView { scene, camera, view, width, height, materials, radiances, warnings })
}
