//! Stage 2, masks and alignment: which photo pixels of a part count, and where on the coarse
//! model each of them is.
//!
//! M_photo comes from the view's label image (M_geo where the view has none), M_geo from the
//! coarse model traced through the view's camera. The model is misaligned, so per part a
//! scale-and-translate warp maps model raster positions onto the photo: initialised from the
//! two masks' bounding boxes and refined by pattern search to maximise their IoU (PhotoScene's
//! supplement, "Alignment and Warping"). A photo pixel is usable when it is labelled with the
//! part, not clipped, not on the boundary of the aligned mask (eroded by one pixel), and its
//! warped model position lands on the same part away from depth edges; the clipped pixels that
//! pass the other tests are kept apart (see [`AlignedPart::clipped`]).

use crate::observe::ViewObservation;

/// Photo raster position = model raster position × `scale` + `offset` (continuous coordinates).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Warp {
    pub scale: [f32; 2],
    pub offset: [f32; 2],
}

impl Warp {
    pub const IDENTITY: Warp = Warp { scale: [1.0, 1.0], offset: [0.0, 0.0] };

    /// Model raster position of photo raster position `p`.
    #[inline]
    pub fn to_model(&self, p: [f32; 2]) -> [f32; 2] {
        [(p[0] - self.offset[0]) / self.scale[0], (p[1] - self.offset[1]) / self.scale[1]]
    }
}

/// Why photo pixels of a part were left out, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Dropped {
    /// Not usable, but read as clipped by the losses and the light solve
    /// ([`AlignedPart::clipped`]).
    pub clipped: usize,
    pub boundary: usize,
    /// The warped model position is on another part, an emitter or nothing.
    pub other_part: usize,
    pub depth_edge: usize,
}

/// One part in one view after alignment.
#[derive(Clone, Debug)]
pub struct AlignedPart {
    pub part: u32,
    pub view: usize,
    pub warp: Warp,
    /// IoU of the masks before and after the warp refinement (1 without labels).
    pub iou_initial: f32,
    pub iou: f32,
    /// |M_photo| and |M_geo|.
    pub photo_pixels: usize,
    pub model_pixels: usize,
    /// Photo pixel indices that count, in raster order.
    pub usable: Vec<u32>,
    /// Pixels that pass every test but are clipped in the photo: their true value is unknown,
    /// only at least the recorded one. They do not count towards a part's usable pixels (the
    /// 500 a fit needs), but the losses compare them with a render clipped the same way
    /// ([`crate::layer::PartView::weight`]) and the light solve takes them as lower bounds:
    /// left out, a partly clipped part would keep only its darker pixels and be fitted too
    /// dark, and holes in the mask would carve up the pattern.
    pub clipped: Vec<u32>,
    pub dropped: Dropped,
}

impl AlignedPart {
    /// Each usable photo pixel, then each clipped one, with the model pixel its warped position
    /// lands on (always inside the raster and on this part: [`align_view`] keeps only such
    /// pixels), both as indices into a raster `width` pixels wide, and whether it is clipped.
    pub fn correspondences(&self, width: usize, height: usize) -> impl Iterator<Item = (usize, usize, bool)> + '_ {
        let usable = self.usable.iter().map(|&i| (i, false));
        usable.chain(self.clipped.iter().map(|&i| (i, true))).filter_map(move |(i, clipped)| {
            let (x, y) = ((i as usize % width) as f32 + 0.5, (i as usize / width) as f32 + 0.5);
            model_pixel(&self.warp, x, y, width, height).map(|j| (i as usize, j, clipped))
        })
    }
}

/// Relative depth jump between 4-neighbours that marks a depth edge.
const DEPTH_EDGE: f32 = 0.05;

/// Aligns every part the view shows; parts absent from the photo (or, with labels, from the
/// model's view) are left out.
pub fn align_view(obs: &ViewObservation, view: usize, n_parts: usize) -> Vec<AlignedPart> {
    (0..n_parts as u32).filter_map(|part| align_part(obs, view, part)).collect()
}

fn align_part(obs: &ViewObservation, view: usize, part: u32) -> Option<AlignedPart> {
    let geo = &obs.geo;
    let (w, h) = (geo.width, geo.height);
    let model_mask: Vec<bool> = geo.part.iter().map(|&p| p == part).collect();
    let photo_mask: Vec<bool> = match &obs.labels {
        Some(l) => l.iter().map(|&p| p == part).collect(),
        None => model_mask.clone(),
    };
    let photo_pixels = photo_mask.iter().filter(|&&m| m).count();
    let model_pixels = model_mask.iter().filter(|&&m| m).count();
    if photo_pixels == 0 || model_pixels == 0 {
        return None;
    }
    let (warp, iou_initial, iou) = if obs.labels.is_some() {
        let masks = Masks { w, h, photo: &photo_mask, model: &model_mask };
        let init = bbox_warp(&masks);
        let iou0 = masks.iou(&init);
        let (refined, iou1) = refine(&masks, init, iou0);
        (refined, iou0, iou1)
    } else {
        (Warp::IDENTITY, 1.0, 1.0)
    };

    let mut usable = Vec::new();
    let mut clipped = Vec::new();
    let mut dropped = Dropped::default();
    let inside = |x: i64, y: i64| x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h;
    for i in 0..w * h {
        if !photo_mask[i] {
            continue;
        }
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        let interior = [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)]
            .iter()
            .all(|&(a, b)| inside(a, b) && photo_mask[b as usize * w + a as usize]);
        if !interior {
            dropped.boundary += 1;
            continue;
        }
        let Some(j) = model_pixel(&warp, x as f32 + 0.5, y as f32 + 0.5, w, h) else {
            dropped.other_part += 1;
            continue;
        };
        if geo.part[j] != part {
            dropped.other_part += 1;
            continue;
        }
        if geo.on_edge(j, DEPTH_EDGE) {
            dropped.depth_edge += 1;
            continue;
        }
        if obs.photo.clipped(i) {
            dropped.clipped += 1;
            clipped.push(i as u32);
        } else {
            usable.push(i as u32);
        }
    }
    Some(AlignedPart { part, view, warp, iou_initial, iou, photo_pixels, model_pixels, usable, clipped, dropped })
}

/// The model pixel under photo raster position (x, y), if inside the image.
pub(crate) fn model_pixel(warp: &Warp, x: f32, y: f32, w: usize, h: usize) -> Option<usize> {
    let [gx, gy] = warp.to_model([x, y]);
    if !(gx >= 0.0 && gy >= 0.0 && gx < w as f32 && gy < h as f32) {
        return None;
    }
    Some(gy as usize * w + gx as usize)
}

struct Masks<'a> {
    w: usize,
    h: usize,
    photo: &'a [bool],
    model: &'a [bool],
}

/// Inclusive pixel bounding box (x0, y0, x1, y1).
fn bbox(mask: &[bool], w: usize) -> [usize; 4] {
    let mut b = [usize::MAX, usize::MAX, 0, 0];
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = (i % w, i / w);
        b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
    }
    b
}

/// The warp that maps the model mask's bounding box onto the photo mask's.
fn bbox_warp(m: &Masks) -> Warp {
    let (p, g) = (bbox(m.photo, m.w), bbox(m.model, m.w));
    let extent = |b: [usize; 4], k: usize| (b[k + 2] - b[k] + 1) as f32;
    let scale = [0, 1].map(|k| (extent(p, k) / extent(g, k)).clamp(0.5, 2.0));
    let offset = [0, 1].map(|k| p[k] as f32 - g[k] as f32 * scale[k]);
    Warp { scale, offset }
}

impl Masks<'_> {
    /// IoU of the photo mask and the warped model mask, over the photo's pixels.
    fn iou(&self, warp: &Warp) -> f32 {
        let (mut inter, mut union) = (0usize, 0usize);
        for i in 0..self.w * self.h {
            let (x, y) = ((i % self.w) as f32 + 0.5, (i / self.w) as f32 + 0.5);
            let warped = model_pixel(warp, x, y, self.w, self.h).is_some_and(|j| self.model[j]);
            inter += (warped && self.photo[i]) as usize;
            union += (warped || self.photo[i]) as usize;
        }
        if union == 0 {
            0.0
        } else {
            inter as f32 / union as f32
        }
    }
}

/// Pattern search over (scale x, scale y, shift x, shift y) for the largest IoU: try a step up
/// and down on each coordinate, keep improvements, halve the steps when none helps. Scales act
/// about the model mask's centroid, so that scale and shift steps are independent.
fn refine(m: &Masks, start: Warp, start_iou: f32) -> (Warp, f32) {
    let centroid = centroid(m.model, m.w);
    let warp_of =
        |x: [f32; 4]| Warp { scale: [x[0], x[1]], offset: [0, 1].map(|k| centroid[k] + x[k + 2] - x[k] * centroid[k]) };
    let mut x = [
        start.scale[0],
        start.scale[1],
        start.offset[0] + start.scale[0] * centroid[0] - centroid[0],
        start.offset[1] + start.scale[1] * centroid[1] - centroid[1],
    ];
    let mut best_iou = start_iou;
    let mut steps = [0.04f32, 0.04, 4.0, 4.0];
    let floor = [0.0025f32, 0.0025, 0.25, 0.25];
    let mut evaluations = 0;
    while steps.iter().zip(&floor).any(|(s, f)| s >= f) && evaluations < 400 {
        let mut improved = false;
        for k in 0..4 {
            for sign in [1.0f32, -1.0] {
                let mut c = x;
                c[k] += sign * steps[k];
                if k < 2 {
                    c[k] = c[k].clamp(0.5, 2.0);
                }
                evaluations += 1;
                let iou = m.iou(&warp_of(c));
                if iou > best_iou + 1e-6 {
                    (x, best_iou, improved) = (c, iou, true);
                }
            }
        }
        if !improved {
            steps.iter_mut().for_each(|s| *s *= 0.5);
        }
    }
    (warp_of(x), best_iou)
}

fn centroid(mask: &[bool], w: usize) -> [f32; 2] {
    let (mut sx, mut sy, mut n) = (0.0f64, 0.0f64, 0usize);
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        sx += (i % w) as f64 + 0.5;
        sy += (i / w) as f64 + 0.5;
        n += 1;
    }
    [(sx / n.max(1) as f64) as f32, (sy / n.max(1) as f64) as f32]
}
