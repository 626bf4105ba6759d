//! The raster the fit works at. A photo of more than [`crate::pipeline::FitOptions`]'s
//! `max_photo_pixels` pixels is fitted at a coarser raster: the photo box-averaged (in linear
//! light) over `factor × factor` blocks, the smallest integer factor that brings it within the
//! budget, cropped to whole blocks with the remainder split evenly around them; the camera is
//! windowed to match ([`Camera::window`]), so every working pixel's ray is the ray through its
//! block's centre. The fit's cost grows with the pixels of its views (G-buffers, alignment,
//! light grids, the light solve's renders) while what it can learn of a part's material does
//! not (a part is fitted on at most `fit_pixels` pixels): a 12-megapixel phone photo at full
//! resolution would take hours.
//!
//! A block whose pixels are clipped anywhere is clipped (its average hides the unknown value);
//! a block's label is the one most of its pixels carry (ties to the smaller label value).

use psc_render::camera::Camera;
use psc_render::image_io;
use serde::{Deserialize, Serialize};

use crate::observe::Photo;

/// Where the working raster of a view lies in its photo.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct WorkingRaster {
    /// Photo pixels per working pixel, per axis (1: the photo itself).
    pub factor: usize,
    /// The photo pixel at the top-left corner of working pixel (0, 0).
    pub origin: [usize; 2],
    pub width: usize,
    pub height: usize,
}

impl WorkingRaster {
    /// The raster for a `width × height` photo and a budget of `max_pixels` (0: no budget).
    pub fn for_photo(width: usize, height: usize, max_pixels: usize) -> WorkingRaster {
        let fits = |k: usize| max_pixels == 0 || (width / k) * (height / k) <= max_pixels;
        let mut factor = 1;
        while !fits(factor) && width / (factor + 1) > 0 && height / (factor + 1) > 0 {
            factor += 1;
        }
        let (w, h) = (width / factor, height / factor);
        WorkingRaster { factor, origin: [(width - w * factor) / 2, (height - h * factor) / 2], width: w, height: h }
    }

    /// Whether this is the photo's own raster (a factor of 1 leaves no remainder to crop).
    pub fn is_identity(&self) -> bool {
        self.factor == 1
    }

    /// The photo's camera (at the photo's size) seen through this raster.
    pub fn camera(&self, camera: &Camera) -> Camera {
        if self.is_identity() {
            camera.clone()
        } else {
            camera.window(self.origin, self.factor, self.width, self.height)
        }
    }

    /// Photo pixel indices (row-major, photo width `photo_width`) of working pixel `i`'s block.
    fn block(&self, i: usize, photo_width: usize) -> impl Iterator<Item = usize> + '_ {
        let (x0, y0) =
            (self.origin[0] + (i % self.width) * self.factor, self.origin[1] + (i / self.width) * self.factor);
        (y0..y0 + self.factor).flat_map(move |y| (x0..x0 + self.factor).map(move |x| y * photo_width + x))
    }

    /// The photo at this raster: linear values averaged over each block, encoded values the
    /// sRGB encoding of the average, clipped where any pixel of the block is.
    pub fn photo(&self, photo: Photo) -> Photo {
        if self.is_identity() {
            return photo;
        }
        let linear =
            image_io::block_average(&photo.linear, photo.width, self.origin, self.factor, self.width, self.height);
        let clip =
            (0..self.width * self.height).map(|i| self.block(i, photo.width).any(|j| photo.clipped(j))).collect();
        let encoded = linear.iter().map(|c: &[f32; 3]| c.map(image_io::linear_to_srgb)).collect();
        Photo::from_parts(self.width, self.height, encoded, linear, clip)
    }

    /// Per-pixel labels at this raster: each block's most frequent value (ties to the smaller).
    pub fn labels(&self, labels: Vec<u32>, photo_width: usize) -> Vec<u32> {
        if self.is_identity() {
            return labels;
        }
        let mut counts: Vec<(u32, usize)> = Vec::new();
        (0..self.width * self.height)
            .map(|i| {
                counts.clear();
                for j in self.block(i, photo_width) {
                    match counts.iter_mut().find(|(v, _)| *v == labels[j]) {
                        Some((_, c)) => *c += 1,
                        None => counts.push((labels[j], 1)),
                    }
                }
                counts.iter().max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0))).map_or(labels[0], |&(v, _)| v)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smallest_factor_within_the_budget_with_the_remainder_split() {
        let r = WorkingRaster::for_photo(320, 240, 131_072);
        assert!(r.is_identity() && (r.width, r.height) == (320, 240));
        assert!(WorkingRaster::for_photo(4032, 3024, 0).is_identity());
        let r = WorkingRaster::for_photo(641, 481, 131_072);
        assert_eq!(r, WorkingRaster { factor: 2, origin: [0, 0], width: 320, height: 240 });
        let r = WorkingRaster::for_photo(4032, 3024, 131_072);
        assert_eq!((r.factor, r.width, r.height), (10, 403, 302));
        assert_eq!(r.origin, [1, 2]);
        assert!(r.width * r.height <= 131_072 && (4032 / 9) * (3024 / 9) > 131_072);
        // A budget below one pixel still leaves one.
        let r = WorkingRaster::for_photo(7, 5, 1);
        assert_eq!((r.width, r.height), (1, 1));
    }

    #[test]
    fn blocks_average_linear_light_and_keep_clipping_and_the_majority_label() {
        let (w, h) = (5, 4);
        let linear: Vec<[f32; 3]> =
            (0..w * h).map(|i| [i as f32 / 40.0, 0.25, if i == 6 { 1.0 } else { 0.0 }]).collect();
        let encoded = linear.iter().map(|c| c.map(image_io::linear_to_srgb)).collect();
        let clip = linear.iter().map(|c| c[2] >= 1.0).collect();
        let photo = Photo::from_parts(w, h, encoded, linear.clone(), clip);
        let r = WorkingRaster::for_photo(w, h, 4);
        assert_eq!(r, WorkingRaster { factor: 2, origin: [0, 0], width: 2, height: 2 });
        let small = r.photo(photo);
        // Block (0, 0) holds photo pixels 0, 1, 5, 6.
        let mean = (linear[0][0] + linear[1][0] + linear[5][0] + linear[6][0]) / 4.0;
        assert!((small.linear[0][0] - mean).abs() < 1e-7 && small.linear[0][1] == 0.25);
        assert!((small.encoded[0][0] - image_io::linear_to_srgb(mean)).abs() < 1e-7);
        assert!(small.clipped(0) && !small.clipped(1) && !small.clipped(3));
        // Block (1, 1) holds pixels 12, 13, 17, 18.
        let labels: Vec<u32> = (0..w * h).map(|i| if i == 13 || i == 18 { 7 } else { 3 }).collect();
        let tied = r.labels(labels.clone(), w);
        assert_eq!(tied[3], 3, "a tie goes to the smaller label");
        let mut more = labels.clone();
        more[12] = 7;
        let more = r.labels(more, w);
        assert_eq!((more[0], more[3]), (3, 7));
    }
}
