//! Colour helpers every image path shares: the sRGB transfer functions and Rec. 709 luminance.
//!
//! Conventions (one for the whole workspace): both transfers clamp their input to [0, 1] and map
//! NaN to 0, so +∞ encodes as white, −∞ and NaN as black, and values out of range never reach the
//! `powf` (which would give NaN for negative inputs). Inside [0, 1] they are the exact IEC
//! 61966-2-1 formulas.

/// Linear to sRGB-encoded, in [0, 1] (see the module docs for out-of-range values).
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB-encoded to linear, in [0, 1] (see the module docs for out-of-range values).
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// A linear value as an 8-bit sRGB code (rounded to nearest).
#[inline]
pub fn linear_to_srgb8(c: f32) -> u8 {
    (linear_to_srgb(c) * 255.0 + 0.5) as u8
}

/// The Rec. 709 / sRGB-primaries weights of R, G and B in luminance (on linear values) and in
/// luma (the same weights on encoded values).
pub const REC709_WEIGHTS: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Rec. 709 / sRGB-primaries luminance of linear RGB.
#[inline]
pub fn luminance(c: [f32; 3]) -> f32 {
    REC709_WEIGHTS[0] * c[0] + REC709_WEIGHTS[1] * c[1] + REC709_WEIGHTS[2] * c[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_values_follow_the_convention() {
        assert_eq!(linear_to_srgb(f32::NAN), 0.0);
        assert_eq!(linear_to_srgb(f32::INFINITY), linear_to_srgb(1.0));
        assert_eq!(linear_to_srgb(f32::NEG_INFINITY), 0.0);
        assert_eq!(linear_to_srgb(-0.5), 0.0);
        assert_eq!(linear_to_srgb(7.0), linear_to_srgb(1.0));
        assert_eq!(srgb_to_linear(f32::NAN), 0.0);
        assert_eq!(srgb_to_linear(1.3), 1.0);
        assert_eq!(srgb_to_linear(-0.1), 0.0);
        assert_eq!(linear_to_srgb8(f32::INFINITY), 255);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
    }

    #[test]
    fn transfers_invert_each_other_and_match_reference_points() {
        for i in 0..=255 {
            let s = i as f32 / 255.0;
            assert_eq!(linear_to_srgb8(srgb_to_linear(s)), i as u8, "code {i}");
        }
        // IEC 61966-2-1: 0.5 linear encodes to 0.7354; 0.5 encoded decodes to 0.2140.
        assert!((linear_to_srgb(0.5) - 0.735_357).abs() < 1e-5);
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        assert!((luminance([1.0, 1.0, 1.0]) - 1.0).abs() < 1e-6);
    }
}
