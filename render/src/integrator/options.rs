//! What a render is asked for ([`RenderOptions`], checked against the resource limits before
//! anything is allocated), what a path is told ([`PathConfig`]), and what comes back
//! ([`RenderOutput`], with the per-light folder it writes).

use psc_base::output::{Replace, StagedDir};

use crate::RenderError;

/// Options of one render.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub width: usize,
    pub height: usize,
    pub spp: u32,
    pub seed: u64,
    /// Mitsuba convention; 6 (the dev scenes' truth renders) by default.
    pub max_depth: u32,
    /// Russian roulette from this depth on (Mitsuba default 5).
    pub rr_depth: u32,
    /// Worker threads (None = rayon's global pool).
    pub threads: Option<usize>,
    /// Also return one image per light slot at unit radiance.
    pub per_light: bool,
    /// Validation only: switch the specular lobe off (pure Lambertian).
    pub diffuse_only: bool,
}

/// What a path needs to know besides its start.
#[derive(Clone, Copy, Debug)]
pub struct PathConfig {
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Select lights for NEE by area (unit radiance) instead of by power.
    pub per_light: bool,
    pub diffuse_only: bool,
    /// Area lights hit by the first segment count nothing (the caller estimates direct light
    /// by sampling the lights instead, as the light grid does).
    pub skip_direct_emitters: bool,
}

impl RenderOptions {
    /// Refuse options that cannot give a meaningful image or that exceed the resource limits
    /// (`psc_base::limits`), before anything is allocated; `slots` = light slots of the scene.
    pub fn check(&self, slots: usize) -> Result<(), RenderError> {
        use psc_base::limits;
        if self.width == 0 || self.height == 0 {
            return Err(RenderError::Invalid(format!("image size {}x{} must be positive", self.width, self.height)));
        }
        if self.spp == 0 {
            return Err(RenderError::Invalid("samples per pixel must be at least 1".into()));
        }
        if self.max_depth == 0 {
            return Err(RenderError::Invalid(
                "max_depth 0 renders nothing (Mitsuba convention: 1 = directly visible emitters, 2 = direct light, \
                 6 = the default)"
                    .into(),
            ));
        }
        limits::check_count("samples per pixel", self.spp as u64, limits::MAX_SPP, "samples")?;
        if let Some(t) = self.threads {
            limits::check_threads(t as u64)?;
        }
        // Per pixel: the slot accumulators, the combined image, and the per-light copies.
        let per_pixel = 12 * (slots as u64 + 1 + if self.per_light { slots as u64 } else { 0 });
        limits::check_image("render", self.width as u64, self.height as u64, per_pixel)?;
        Ok(())
    }

    pub fn path_config(&self) -> PathConfig {
        PathConfig {
            max_depth: self.max_depth,
            rr_depth: self.rr_depth,
            per_light: self.per_light,
            diffuse_only: self.diffuse_only,
            skip_direct_emitters: false,
        }
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 320,
            height: 240,
            spp: 64,
            seed: 0,
            max_depth: 6,
            rr_depth: 5,
            threads: None,
            per_light: false,
            diffuse_only: false,
        }
    }
}

/// A finished render.
pub struct RenderOutput {
    pub width: usize,
    pub height: usize,
    /// Linear RGB, row 0 at the top.
    pub image: Vec<[f32; 3]>,
    /// With `per_light`: (slot name, image at unit radiance) per area light, then "environment"
    /// if the scene has one.
    pub per_light: Vec<(String, Vec<[f32; 3]>)>,
    /// Rays cast (camera, bounce and shadow rays).
    pub rays: u64,
    pub seconds: f64,
}

impl RenderOutput {
    /// Write the per-light images (`<slot>.exr`, linear, unit radiance) and `combined.exr` (the
    /// render) as the new folder `dest`, which appears whole or not at all; an existing `dest`
    /// is refused unless `replace` is `Replace::Yes`.
    pub fn write_per_light_folder(&self, dest: &std::path::Path, replace: Replace) -> Result<(), RenderError> {
        let staged = StagedDir::new(dest, replace)?;
        let names: Vec<&str> = self.per_light.iter().map(|(n, _)| n.as_str()).collect();
        for ((_, img), file) in self.per_light.iter().zip(slot_file_names(&names)) {
            crate::image_io::write_rgb(&staged.path().join(file), self.width, self.height, img)?;
        }
        crate::image_io::write_rgb(&staged.path().join("combined.exr"), self.width, self.height, &self.image)?;
        staged.commit()?;
        Ok(())
    }
}

/// File names (`<name>.exr`) for light slots: characters other than ASCII letters, digits, `_`,
/// `-` and `.` become `_` (a light named `../x` cannot write outside the folder), a leading `.`
/// too, and names that collide (with each other or with `combined`) get a `_<k>` suffix.
pub fn slot_file_names(names: &[&str]) -> Vec<String> {
    let mut used: Vec<String> = vec!["combined".into()];
    names
        .iter()
        .map(|n| {
            let mut base: String =
                n.chars().map(|c| if c.is_ascii_alphanumeric() || "_-.".contains(c) { c } else { '_' }).collect();
            if base.is_empty() || base.starts_with('.') {
                base.insert(0, '_');
            }
            let mut name = base.clone();
            let mut k = 1;
            while used.contains(&name) {
                name = format!("{base}_{k}");
                k += 1;
            }
            used.push(name.clone());
            format!("{name}.exr")
        })
        .collect()
}
