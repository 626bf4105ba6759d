//! The region's geometry at every scale: the working-resolution reduction of the crop, the
//! Gaussian pyramid (5-tap binomial blur, then every second pixel), the pooling weights of each
//! level, and the adjoints of both reductions.
//!
//! Masking is by exact erosion. A value at any level depends on a known footprint of crop
//! pixels; its weight is the minimum of the crop weights over that footprint (outside the crop
//! counts as 0). So the working-resolution pixel takes the minimum over its box, a pyramid
//! pixel the minimum over its 5×5 parents, and a filter response (pooling weight) the minimum
//! over its 9×9 window. A response with a non-zero weight therefore reads only crop pixels of
//! non-zero weight: whatever lies outside the mask (even NaN) cannot change the statistics,
//! and the gradient there is exactly zero.

use std::ops::Range;

use super::filters::RADIUS;

/// The binomial blur of a pyramid reduction, taps at offsets −2..=2.
const BLUR: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// One pyramid level of the region.
#[derive(Clone, Debug)]
pub(super) struct Level {
    pub width: usize,
    pub height: usize,
    /// Rows and columns of the bounding box of the non-zero pooling weights (empty ranges when
    /// there are none). The bank is evaluated only inside it.
    pub rows: Range<usize>,
    pub cols: Range<usize>,
    /// Pooling weights over the bounding box, row-major, normalised to sum 1.
    pub pool: Vec<f32>,
    /// Sum of the pooling weights before normalisation, in pixels of this level.
    pub support: f64,
    pub active: bool,
}

/// The working-resolution crop and its pyramid levels.
#[derive(Clone, Debug)]
pub(super) struct Geometry {
    pub width: usize,
    pub height: usize,
    /// Working-resolution reduction factor (1 = full resolution).
    pub factor: usize,
    /// Levels 0.. up to the last active one (levels past it are not built).
    pub levels: Vec<Level>,
    /// Weights of the working-resolution pixels (minimum over each box).
    pub weight0: Vec<f32>,
}

impl Geometry {
    /// `weight` is the validated crop weight (`width × height`, values in [0, 1]).
    pub fn new(
        width: usize,
        height: usize,
        weight: &[f32],
        factor: usize,
        num_levels: usize,
        min_support: f64,
    ) -> Geometry {
        let (w0, h0) = (width.div_ceil(factor), height.div_ceil(factor));
        let mut v = vec![0.0f32; w0 * h0];
        for (y0, row) in v.chunks_exact_mut(w0).enumerate() {
            for (x0, out) in row.iter_mut().enumerate() {
                let mut m = f32::INFINITY;
                for y in y0 * factor..((y0 + 1) * factor).min(height) {
                    for x in x0 * factor..((x0 + 1) * factor).min(width) {
                        m = m.min(weight[y * width + x]);
                    }
                }
                *out = m;
            }
        }
        let weight0 = v.clone();
        let (mut lw, mut lh) = (w0, h0);
        let mut levels = Vec::with_capacity(num_levels);
        for l in 0..num_levels {
            if l > 0 {
                let (nw, nh) = (lw.div_ceil(2), lh.div_ceil(2));
                v = erode_reduce(&v, lw, lh, nw, nh);
                (lw, lh) = (nw, nh);
            }
            levels.push(pool_level(&v, lw, lh, min_support));
        }
        let last = levels.iter().rposition(|l| l.active).map_or(0, |i| i + 1);
        levels.truncate(last);
        Geometry { width, height, factor, levels, weight0 }
    }

    pub fn working_size(&self) -> (usize, usize) {
        (self.width.div_ceil(self.factor), self.height.div_ceil(self.factor))
    }

    /// Working-resolution planes of the crop image: each working pixel is the mean of its box
    /// of crop pixels, then projected on `axes` (one plane per axis).
    pub fn reduce_image(&self, image: &[[f32; 3]], axes: &[[f32; 3]], planes: &mut [Vec<f32>]) {
        let (w0, h0) = self.working_size();
        let f = self.factor;
        for p in planes.iter_mut() {
            p.resize(w0 * h0, 0.0);
        }
        if f == 1 {
            for (i, px) in image.iter().enumerate() {
                for (plane, a) in planes.iter_mut().zip(axes) {
                    plane[i] = a[0] * px[0] + a[1] * px[1] + a[2] * px[2];
                }
            }
            return;
        }
        for y0 in 0..h0 {
            for x0 in 0..w0 {
                let mut sum = [0.0f32; 3];
                let (ys, xs) = (y0 * f..((y0 + 1) * f).min(self.height), x0 * f..((x0 + 1) * f).min(self.width));
                let count = (ys.len() * xs.len()) as f32;
                for y in ys {
                    for px in &image[y * self.width + xs.start..y * self.width + xs.end] {
                        for c in 0..3 {
                            sum[c] += px[c];
                        }
                    }
                }
                for (plane, a) in planes.iter_mut().zip(axes) {
                    plane[y0 * w0 + x0] = (a[0] * sum[0] + a[1] * sum[1] + a[2] * sum[2]) / count;
                }
            }
        }
    }

    /// The adjoint of [`Geometry::reduce_image`]: writes (not adds) the crop gradient.
    pub fn reduce_image_adjoint(&self, d_planes: &[Vec<f32>], axes: &[[f32; 3]], grad: &mut [[f32; 3]]) {
        let (w0, h0) = self.working_size();
        let f = self.factor;
        let pixel = |i: usize, scale: f32| -> [f32; 3] {
            let mut g = [0.0f32; 3];
            for (plane, a) in d_planes.iter().zip(axes) {
                let d = plane[i] * scale;
                for c in 0..3 {
                    g[c] += a[c] * d;
                }
            }
            g
        };
        if f == 1 {
            for (i, g) in grad.iter_mut().enumerate() {
                *g = pixel(i, 1.0);
            }
            return;
        }
        for y0 in 0..h0 {
            for x0 in 0..w0 {
                let (ys, xs) = (y0 * f..((y0 + 1) * f).min(self.height), x0 * f..((x0 + 1) * f).min(self.width));
                let g = pixel(y0 * w0 + x0, 1.0 / (ys.len() * xs.len()) as f32);
                for y in ys {
                    grad[y * self.width + xs.start..y * self.width + xs.end].fill(g);
                }
            }
        }
    }
}

/// Pooling weights of a level with working weights `v`: the minimum over each 9×9 window.
fn pool_level(v: &[f32], w: usize, h: usize, min_support: f64) -> Level {
    let r = RADIUS;
    // Separable minimum: over columns of each row, then over rows.
    let mut horiz = vec![0.0f32; w * h];
    for y in 0..h {
        for x in r..w.saturating_sub(r) {
            horiz[y * w + x] = v[y * w + x - r..=y * w + x + r].iter().copied().fold(f32::INFINITY, f32::min);
        }
    }
    let mut pool = vec![0.0f32; w * h];
    for y in r..h.saturating_sub(r) {
        for x in 0..w {
            pool[y * w + x] = (y - r..=y + r).map(|yy| horiz[yy * w + x]).fold(f32::INFINITY, f32::min);
        }
    }
    // Bounding box of the non-zero weights: (min, max + 1) per axis.
    let (mut y0, mut y1, mut x0, mut x1) = (usize::MAX, 0, usize::MAX, 0);
    for (i, _) in pool.iter().enumerate().filter(|(_, &p)| p > 0.0) {
        let (x, y) = (i % w, i / w);
        (y0, y1, x0, x1) = (y0.min(y), y1.max(y + 1), x0.min(x), x1.max(x + 1));
    }
    if y0 >= y1 {
        return Level { width: w, height: h, rows: 0..0, cols: 0..0, pool: Vec::new(), support: 0.0, active: false };
    }
    let (rows, cols) = (y0..y1, x0..x1);
    let support: f64 = pool.iter().map(|&p| f64::from(p)).sum();
    let mut boxed = Vec::with_capacity(rows.len() * cols.len());
    for y in rows.clone() {
        boxed.extend(pool[y * w + cols.start..y * w + cols.end].iter().map(|&p| (f64::from(p) / support) as f32));
    }
    let active = support >= min_support.max(f64::MIN_POSITIVE);
    Level { width: w, height: h, rows, cols, pool: boxed, support, active }
}

/// Weights of the next pyramid level: the minimum over each pixel's 5×5 parents (0 outside).
fn erode_reduce(v: &[f32], w: usize, h: usize, nw: usize, nh: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; nw * nh];
    for y2 in 0..nh {
        for x2 in 0..nw {
            let (cy, cx) = (2 * y2, 2 * x2);
            if cy < 2 || cx < 2 || cy + 2 >= h || cx + 2 >= w {
                continue; // a parent lies outside the level
            }
            let mut m = f32::INFINITY;
            for y in cy - 2..=cy + 2 {
                for &p in &v[y * w + cx - 2..=y * w + cx + 2] {
                    m = m.min(p);
                }
            }
            out[y2 * nw + x2] = m;
        }
    }
    out
}

/// One pyramid reduction: blur with the binomial filter (zero outside), keep even pixels.
/// `dst` is `⌈w/2⌉ × ⌈h/2⌉`; `tmp` is scratch.
pub(super) fn reduce(src: &[f32], w: usize, h: usize, dst: &mut Vec<f32>, tmp: &mut Vec<f32>) {
    let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
    tmp.clear();
    tmp.resize(h * nw, 0.0);
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        for x2 in 0..nw {
            let mut s = 0.0f32;
            for (j, &b) in BLUR.iter().enumerate() {
                let x = (2 * x2 + j).wrapping_sub(2);
                if x < w {
                    s += b * row[x];
                }
            }
            tmp[y * nw + x2] = s;
        }
    }
    dst.clear();
    dst.resize(nw * nh, 0.0);
    for y2 in 0..nh {
        let out = &mut dst[y2 * nw..(y2 + 1) * nw];
        for (i, &b) in BLUR.iter().enumerate() {
            let y = (2 * y2 + i).wrapping_sub(2);
            if y < h {
                super::filters::axpy(b, &tmp[y * nw..(y + 1) * nw], out);
            }
        }
    }
}

/// The adjoint of [`reduce`]: adds the gradient of `src` given that of `dst`.
pub(super) fn reduce_adjoint(d_dst: &[f32], w: usize, h: usize, d_src: &mut [f32], tmp: &mut Vec<f32>) {
    let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
    tmp.clear();
    tmp.resize(h * nw, 0.0);
    for y2 in 0..nh {
        let d = &d_dst[y2 * nw..(y2 + 1) * nw];
        for (i, &b) in BLUR.iter().enumerate() {
            let y = (2 * y2 + i).wrapping_sub(2);
            if y < h {
                super::filters::axpy(b, d, &mut tmp[y * nw..(y + 1) * nw]);
            }
        }
    }
    for y in 0..h {
        let row = &mut d_src[y * w..(y + 1) * w];
        for x2 in 0..nw {
            let d = tmp[y * nw + x2];
            for (j, &b) in BLUR.iter().enumerate() {
                let x = (2 * x2 + j).wrapping_sub(2);
                if x < w {
                    row[x] += b * d;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ⟨reduce(a), b⟩ = ⟨a, reduceᵀ(b)⟩ for random a, b (odd and even sizes).
    #[test]
    fn reduce_adjoint_is_the_transpose() {
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((rng >> 40) as f32 / (1u64 << 24) as f32) - 0.5
        };
        for (w, h) in [(9usize, 7usize), (10, 12), (1, 5), (16, 16)] {
            let a: Vec<f32> = (0..w * h).map(|_| next()).collect();
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let b: Vec<f32> = (0..nw * nh).map(|_| next()).collect();
            let (mut ra, mut tmp) = (Vec::new(), Vec::new());
            reduce(&a, w, h, &mut ra, &mut tmp);
            let mut rtb = vec![0.0f32; w * h];
            reduce_adjoint(&b, w, h, &mut rtb, &mut tmp);
            let lhs: f64 = ra.iter().zip(&b).map(|(x, y)| f64::from(x * y)).sum();
            let rhs: f64 = a.iter().zip(&rtb).map(|(x, y)| f64::from(x * y)).sum();
            assert!((lhs - rhs).abs() < 1e-5, "{w}x{h}: {lhs} vs {rhs}");
        }
    }
}
