//! The pictures of the page: images read as 8-bit sRGB, the difference of photo and render,
//! crops around a part, thumbnails of baked maps, and all of them encoded as PNG `data:` URIs.

use std::path::Path;

use psc_render::scene::Labels;

/// An 8-bit sRGB RGB image, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8 {
    pub width: usize,
    pub height: usize,
    /// `3 * width * height` bytes, r, g, b per pixel.
    pub data: Vec<u8>,
}

/// How much the difference image amplifies |photo − render|: errors of a quarter of full scale
/// already show white (at ×8 the path tracer's noise hid the structure of the errors).
pub const DIFFERENCE_GAIN: f32 = 4.0;

impl Rgb8 {
    fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * self.width + x);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// The image read from a PNG or JPEG, as stored (sRGB), checked against the pixel limit
    /// before decoding; errors name the file.
    pub fn read(path: &Path) -> Result<Rgb8, String> {
        psc_render::image_io::dimensions(path).map_err(|e| e.to_string())?;
        let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?.to_rgb8();
        Ok(Rgb8 { width: img.width() as usize, height: img.height() as usize, data: img.into_raw() })
    }

    /// The image box-downsampled in linear light: `width × height` blocks of `factor × factor`
    /// pixels, the first at `origin` (how `psc fit` sees a photo it fits at a working raster).
    pub fn block_average(&self, origin: [usize; 2], factor: usize, width: usize, height: usize) -> Rgb8 {
        use psc_base::color::{linear_to_srgb8, srgb_to_linear};
        let linear: Vec<[f32; 3]> =
            self.data.chunks(3).map(|p| [0, 1, 2].map(|c| srgb_to_linear(f32::from(p[c]) / 255.0))).collect();
        let small = psc_render::image_io::block_average(&linear, self.width, origin, factor, width, height);
        Rgb8 { width, height, data: small.iter().flat_map(|p| p.map(linear_to_srgb8)).collect() }
    }

    /// The inverse of [`Rgb8::block_average`] for looking at a downsampled image beside its
    /// original: the `width × height` image in which every pixel of this one covers its
    /// `factor × factor` block at `origin` (nearest); pixels outside the blocks are black.
    pub fn blocks_at(&self, origin: [usize; 2], factor: usize, width: usize, height: usize) -> Rgb8 {
        let mut data = vec![0u8; 3 * width * height];
        for y in 0..height {
            for x in 0..width {
                let (Some(bx), Some(by)) = (x.checked_sub(origin[0]), y.checked_sub(origin[1])) else { continue };
                let (sx, sy) = (bx / factor, by / factor);
                if sx < self.width && sy < self.height {
                    data[3 * (y * width + x)..][..3].copy_from_slice(&self.pixel(sx, sy));
                }
            }
        }
        Rgb8 { width, height, data }
    }

    /// PNG bytes of the image.
    pub fn png(&self) -> Vec<u8> {
        use image::ImageEncoder;
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&self.data, self.width as u32, self.height as u32, image::ExtendedColorType::Rgb8)
            .expect("encoding a well-formed RGB buffer into memory cannot fail");
        out
    }

    /// The image as a `data:image/png;base64,…` URI.
    pub fn data_uri(&self) -> String {
        format!("data:image/png;base64,{}", psc_base::base64::encode(&self.png()))
    }

    /// The image shrunk (by area averaging) so that neither side exceeds `max_side`; unchanged
    /// when it already fits.
    pub fn fit_within(&self, max_side: usize) -> Rgb8 {
        let longest = self.width.max(self.height);
        if longest <= max_side || longest == 0 {
            return self.clone();
        }
        let w = (self.width * max_side / longest).max(1);
        let h = (self.height * max_side / longest).max(1);
        let mut data = Vec::with_capacity(3 * w * h);
        for y in 0..h {
            let (y0, y1) = (y * self.height / h, ((y + 1) * self.height / h).max(y * self.height / h + 1));
            for x in 0..w {
                let (x0, x1) = (x * self.width / w, ((x + 1) * self.width / w).max(x * self.width / w + 1));
                let mut sum = [0u32; 3];
                for sy in y0..y1 {
                    for sx in x0..x1 {
                        let p = self.pixel(sx, sy);
                        for c in 0..3 {
                            sum[c] += p[c] as u32;
                        }
                    }
                }
                let n = ((y1 - y0) * (x1 - x0)) as u32;
                data.extend(sum.iter().map(|s| ((s + n / 2) / n) as u8));
            }
        }
        Rgb8 { width: w, height: h, data }
    }
}

/// |photo − render| per sRGB channel, times [`DIFFERENCE_GAIN`], and the mean absolute
/// difference (in [0, 1], before the gain); `None` when the sizes differ.
pub fn difference(photo: &Rgb8, render: &Rgb8) -> Option<(Rgb8, f64)> {
    if photo.width != render.width || photo.height != render.height {
        return None;
    }
    let mut total = 0u64;
    let data = photo
        .data
        .iter()
        .zip(&render.data)
        .map(|(&a, &b)| {
            let d = a.abs_diff(b);
            total += d as u64;
            (d as f32 * DIFFERENCE_GAIN).min(255.0).round() as u8
        })
        .collect();
    let mean = total as f64 / (255.0 * photo.data.len().max(1) as f64);
    Some((Rgb8 { width: photo.width, height: photo.height, data }, mean))
}

/// Inclusive pixel bounds `(x0, y0, x1, y1)` of the label values in `values`, or `None` when
/// no pixel carries one.
pub fn label_bounds(labels: &Labels, values: &[u16]) -> Option<(usize, usize, usize, usize)> {
    let mut b: Option<(usize, usize, usize, usize)> = None;
    for (i, l) in labels.data.iter().enumerate() {
        if values.contains(l) {
            let (x, y) = (i % labels.width, i / labels.width);
            b = Some(match b {
                None => (x, y, x, y),
                Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
            });
        }
    }
    b
}

/// The part of `image` around `bounds` (grown by an eighth of its size, at least 4 pixels, on
/// each side), with the pixels the labels do not give to the part dimmed to a third, so the part
/// stands out from its surroundings. `labels` must have the image's size.
pub fn part_crop(image: &Rgb8, labels: &Labels, values: &[u16], bounds: (usize, usize, usize, usize)) -> Rgb8 {
    let (x0, y0, x1, y1) = bounds;
    let pad_x = ((x1 - x0 + 1) / 8).max(4);
    let pad_y = ((y1 - y0 + 1) / 8).max(4);
    let (cx0, cy0) = (x0.saturating_sub(pad_x), y0.saturating_sub(pad_y));
    let (cx1, cy1) = ((x1 + pad_x).min(image.width - 1), (y1 + pad_y).min(image.height - 1));
    let (w, h) = (cx1 - cx0 + 1, cy1 - cy0 + 1);
    let mut data = Vec::with_capacity(3 * w * h);
    for y in cy0..=cy1 {
        for x in cx0..=cx1 {
            let inside = values.contains(&labels.data[y * labels.width + x]);
            let p = image.pixel(x, y);
            data.extend(p.iter().map(|&c| if inside { c } else { c / 3 }));
        }
    }
    Rgb8 { width: w, height: h, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: usize, height: usize, f: impl Fn(usize, usize) -> [u8; 3]) -> Rgb8 {
        let f = &f;
        let data = (0..height).flat_map(|y| (0..width).flat_map(move |x| f(x, y))).collect::<Vec<_>>();
        Rgb8 { width, height, data }
    }

    #[test]
    fn blocks_at_undoes_the_block_average_of_a_blocky_image() {
        let small = image(3, 2, |x, y| [x as u8 * 50, y as u8 * 100, 9]);
        let big = small.blocks_at([1, 0], 2, 8, 5);
        assert_eq!(big.pixel(0, 0), [0, 0, 0], "left of the blocks");
        assert_eq!(
            (big.pixel(1, 0), big.pixel(2, 1), big.pixel(6, 3)),
            (small.pixel(0, 0), small.pixel(0, 0), small.pixel(2, 1))
        );
        assert_eq!((big.pixel(7, 0), big.pixel(1, 4)), ([0, 0, 0], [0, 0, 0]), "right of and below the blocks");
        assert_eq!(big.block_average([1, 0], 2, 3, 2), small);
    }

    #[test]
    fn png_round_trips_through_the_decoder() {
        let img = image(5, 3, |x, y| [x as u8 * 40, y as u8 * 80, 7]);
        let back = image::load_from_memory(&img.png()).unwrap().to_rgb8();
        assert_eq!((back.width(), back.height()), (5, 3));
        assert_eq!(back.into_raw(), img.data);
        assert!(img.data_uri().starts_with("data:image/png;base64,iVBORw0KGgo"));
    }

    #[test]
    fn difference_is_amplified_and_averaged() {
        let a = image(2, 1, |_, _| [100, 100, 100]);
        let b = image(2, 1, |x, _| if x == 0 { [100, 110, 90] } else { [0, 255, 100] });
        let (d, mean) = difference(&a, &b).unwrap();
        assert_eq!(d.data, vec![0, 40, 40, 255, 255, 0]);
        let expected = (10 + 10 + 100 + 155) as f64 / (255.0 * 6.0); // the two zero channels count in the mean
        assert!((mean - expected).abs() < 1e-12);
        assert!(difference(&a, &image(1, 1, |_, _| [0; 3])).is_none());
    }

    #[test]
    fn shrinking_averages_blocks_and_keeps_the_aspect() {
        let img = image(8, 4, |x, _| if x < 4 { [0; 3] } else { [200; 3] });
        let s = img.fit_within(4);
        assert_eq!((s.width, s.height), (4, 2));
        assert_eq!(s.pixel(0, 0), [0; 3]);
        assert_eq!(s.pixel(3, 1), [200; 3]);
        assert_eq!(img.fit_within(8), img);
    }

    #[test]
    fn crops_around_the_labelled_pixels_and_dims_the_rest() {
        let labels = Labels {
            width: 20,
            height: 10,
            data: (0..200)
                .map(|i| if (8..12).contains(&(i % 20)) && (3..6).contains(&(i / 20)) { 4 } else { 1 })
                .collect(),
        };
        let img = image(20, 10, |_, _| [90, 90, 90]);
        let b = label_bounds(&labels, &[4]).unwrap();
        assert_eq!(b, (8, 3, 11, 5));
        assert!(label_bounds(&labels, &[9]).is_none());
        let c = part_crop(&img, &labels, &[4], b);
        assert_eq!((c.width, c.height), (12, 10)); // 4 px of padding, clipped at the top and bottom
        assert_eq!(c.pixel(0, 0), [30; 3]);
        assert_eq!(c.pixel(4, 3), [90; 3]);
    }
}
