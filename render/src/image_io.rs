//! Image input and output: sRGB PNG/JPEG (8/16 bit), linear EXR, label images. Every file is
//! written atomically (`psc_base::output`), so a reader never sees half of one.

use std::io::Cursor;
use std::path::Path;

use crate::RenderError;

/// A linear RGB float image, row 0 at the top.
#[derive(Clone, Debug)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<[f32; 3]>,
}

pub use psc_base::color::{linear_to_srgb, srgb_to_linear};

fn is_exr(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// Memory a full decode needs per pixel: the decoder's buffer (up to 16-bit RGBA, 8 bytes), the
/// float conversion (12) and the result (12).
const DECODE_BYTES_PER_PIXEL: u64 = 32;

/// Width and height of a PNG/JPEG/EXR without decoding its pixels; refused (naming the file)
/// when over the pixel limit (`psc_base::limits::MAX_PIXELS`), whatever the file's size.
pub fn dimensions(path: &Path) -> Result<(usize, usize), RenderError> {
    let (w, h) = header_dimensions(path)?;
    psc_base::limits::check_image(&format!("{}: image", path.display()), w as u64, h as u64, 0)?;
    Ok((w, h))
}

/// Check the header of an image about to be decoded against the pixel limit and its decoded
/// size against the memory budget.
fn check_decodable(path: &Path, bytes_per_pixel: u64) -> Result<(), RenderError> {
    let (w, h) = header_dimensions(path)?;
    psc_base::limits::check_image(&format!("{}: image", path.display()), w as u64, h as u64, bytes_per_pixel)?;
    Ok(())
}

fn header_dimensions(path: &Path) -> Result<(usize, usize), RenderError> {
    crate::json::check_file(path, "an image")?;
    if is_exr(path) {
        let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| RenderError::image(path, e))?;
        let header = meta.headers.first().ok_or_else(|| RenderError::image(path, "EXR without layers"))?;
        Ok((header.layer_size.width(), header.layer_size.height()))
    } else {
        let (w, h) = image::image_dimensions(path).map_err(|e| RenderError::image(path, e))?;
        Ok((w as usize, h as usize))
    }
}

/// Read an RGB image as linear floats. PNG/JPEG values are decoded from sRGB when `srgb`
/// (else divided by the format's maximum); EXR is taken as linear.
pub fn read_rgb(path: &Path, srgb: bool) -> Result<RgbImage, RenderError> {
    check_decodable(path, DECODE_BYTES_PER_PIXEL)?;
    if is_exr(path) {
        let img = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |res, _| RgbImage {
                width: res.width(),
                height: res.height(),
                data: vec![[0.0; 3]; res.width() * res.height()],
            },
            |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = img.width;
                img.data[pos.y() * w + pos.x()] = [r, g, b];
            },
        )
        .map_err(|e| RenderError::image(path, e))?;
        return Ok(img.layer_data.channel_data.pixels);
    }
    let dynimg = image::open(path).map_err(|e| RenderError::image(path, e))?;
    let img = dynimg.to_rgb32f(); // 8/16-bit values mapped to [0, 1]
    let (w, h) = (img.width() as usize, img.height() as usize);
    let conv = |c: f32| if srgb { srgb_to_linear(c) } else { c };
    let data = img.pixels().map(|p| [conv(p[0]), conv(p[1]), conv(p[2])]).collect();
    Ok(RgbImage { width: w, height: h, data })
}

/// Read a part-label image, returning its values as stored. A PNG may be grayscale (1, 2, 4, 8 or
/// 16 bit) or indexed (1, 2, 4 or 8 bit), whose index is the label, as segmentation datasets
/// store label maps (the palette's colours are ignored); other formats must decode to 8- or
/// 16-bit grayscale. Anything else is refused, saying what the file holds.
pub fn read_labels(path: &Path) -> Result<(usize, usize, Vec<u16>), RenderError> {
    check_decodable(path, 4)?;
    // By extension, as `image` chose the decoder that read the size just checked.
    if image::ImageFormat::from_path(path).ok() == Some(image::ImageFormat::Png) {
        return read_png_labels(path);
    }
    let dynimg = image::open(path).map_err(|e| RenderError::image(path, e))?;
    let (w, h) = (dynimg.width() as usize, dynimg.height() as usize);
    let data = match dynimg {
        image::DynamicImage::ImageLuma8(b) => b.into_raw().into_iter().map(u16::from).collect(),
        image::DynamicImage::ImageLuma16(b) => b.into_raw(),
        other => return Err(not_a_label_image(path, &describe_color(other.color()))),
    };
    Ok((w, h, data))
}

/// The samples of a grayscale or indexed PNG, through `png` rather than `image`: `image` expands
/// a palette to RGB and scales 1-, 2- and 4-bit gray to 8 bits, losing the stored values.
fn read_png_labels(path: &Path) -> Result<(usize, usize, Vec<u16>), RenderError> {
    let failed = |e: png::DecodingError| RenderError::image(path, format!("PNG decoding failed: {e}"));
    let file = std::fs::File::open(path).map_err(|e| RenderError::io(path, e))?;
    // The decoder's default is no transformations: samples come out as stored.
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().map_err(failed)?;
    let depth = reader.info().bit_depth as usize;
    let refused = match reader.info().color_type {
        png::ColorType::Grayscale | png::ColorType::Indexed => None,
        png::ColorType::GrayscaleAlpha => Some("grayscale with alpha"),
        png::ColorType::Rgb => Some("RGB colour"),
        png::ColorType::Rgba => Some("RGBA colour"),
    };
    if let Some(kind) = refused {
        return Err(not_a_label_image(path, &format!("{depth}-bit {kind}")));
    }
    let size = reader.output_buffer_size().ok_or_else(|| failed(png::DecodingError::LimitsExceeded))?;
    // Zeroed: deinterlacing sub-byte samples ORs them into place.
    let mut buf = vec![0; size];
    let frame = reader.next_frame(&mut buf).map_err(failed)?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let rows = buf[..frame.buffer_size()].chunks_exact(frame.line_size);
    let data = match depth {
        16 => rows.flat_map(|r| r.chunks_exact(2).map(|s| u16::from_be_bytes([s[0], s[1]]))).collect(),
        bits => {
            // Samples are packed most significant bit first, each row padded to whole bytes.
            let mask = (1u16 << bits) - 1;
            rows.flat_map(|r| (0..w).map(move |x| u16::from(r[x * bits / 8] >> (8 - bits - x * bits % 8)) & mask))
                .collect()
        }
    };
    Ok((w, h, data))
}

fn not_a_label_image(path: &Path, kind: &str) -> RenderError {
    RenderError::image(
        path,
        format!(
            "a label image must be grayscale (the labels as gray levels) or a palette PNG (the labels as \
             palette indices), this one is {kind}"
        ),
    )
}

/// A decoded colour type in words.
fn describe_color(c: image::ColorType) -> String {
    use image::ColorType as C;
    let bits = c.bits_per_pixel() / u16::from(c.channel_count());
    let kind = match c {
        C::L8 | C::L16 => "grayscale",
        C::La8 | C::La16 => "grayscale with alpha",
        C::Rgb8 | C::Rgb16 | C::Rgb32F => "RGB colour",
        C::Rgba8 | C::Rgba16 | C::Rgba32F => "RGBA colour",
        _ => return format!("{c:?}"),
    };
    format!("{bits}-bit {kind}")
}

/// Write `bytes` to `path` atomically (`psc_base::output::write_atomic`: a temporary in the same
/// folder, synced, renamed into place; removed on error and on SIGINT/SIGTERM).
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<(), RenderError> {
    Ok(psc_base::output::write_atomic(path, bytes)?)
}

/// Encode an RGB float image as an uncompressed-float EXR in memory.
pub fn encode_exr(width: usize, height: usize, data: &[[f32; 3]]) -> Result<Vec<u8>, RenderError> {
    use exr::prelude::*;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = data[y * width + x];
        (p[0], p[1], p[2])
    });
    let mut image = Image::from_channels((width, height), channels);
    // Blocks in increasing order: parallel compression must not make the file's bytes depend
    // on which tile finished first (same inputs, same file).
    image.layer_data.encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
    let mut buf = Cursor::new(Vec::new());
    image.write().to_buffered(&mut buf).map_err(|e| RenderError::Invalid(format!("EXR encoding failed: {e}")))?;
    Ok(buf.into_inner())
}

fn encode_png(img: image::DynamicImage) -> Result<Vec<u8>, RenderError> {
    let mut buf = Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png)
        .map_err(|e| RenderError::Invalid(format!("PNG encoding failed: {e}")))?;
    Ok(buf.into_inner())
}

/// Write a linear image: `.exr` as linear float, `.png` as 8-bit sRGB (clipped to [0, 1]; NaN
/// black, +∞ white: `psc_base::color`).
pub fn write_rgb(path: &Path, width: usize, height: usize, data: &[[f32; 3]]) -> Result<(), RenderError> {
    assert_eq!(data.len(), width * height);
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    let bytes = match ext.as_deref() {
        Some("exr") => encode_exr(width, height, data)?,
        Some("png") => {
            let raw: Vec<u8> = data.iter().flat_map(|p| p.map(psc_base::color::linear_to_srgb8)).collect();
            let buf = image::RgbImage::from_raw(width as u32, height as u32, raw).expect("sized buffer");
            encode_png(image::DynamicImage::ImageRgb8(buf))?
        }
        _ => {
            return Err(RenderError::Invalid(format!(
                "{}: output must end in .exr (linear) or .png (sRGB)",
                path.display()
            )))
        }
    };
    atomic_write(path, &bytes)
}

/// Write a 16-bit grayscale PNG (label images, part ids).
pub fn write_gray16(path: &Path, width: usize, height: usize, data: &[u16]) -> Result<(), RenderError> {
    let buf = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width as u32, height as u32, data.to_vec())
        .expect("sized buffer");
    atomic_write(path, &encode_png(image::DynamicImage::ImageLuma16(buf))?)
}

/// The `out_width × out_height` image whose pixel `(i, j)` is the mean of the `factor × factor`
/// block of `data` (row-major, `width` wide) whose top-left pixel is `origin + factor·(i, j)`:
/// a box downsampling, in whatever space `data` is in (linear light, for a camera's image).
pub fn block_average(
    data: &[[f32; 3]],
    width: usize,
    origin: [usize; 2],
    factor: usize,
    out_width: usize,
    out_height: usize,
) -> Vec<[f32; 3]> {
    let inverse = 1.0 / (factor * factor) as f64;
    (0..out_width * out_height)
        .map(|i| {
            let (x0, y0) = (origin[0] + (i % out_width) * factor, origin[1] + (i / out_width) * factor);
            let mut sum = [0.0f64; 3];
            for row in data[y0 * width..].chunks(width).take(factor) {
                for p in &row[x0..x0 + factor] {
                    for c in 0..3 {
                        sum[c] += f64::from(p[c]);
                    }
                }
            }
            sum.map(|s| (s * inverse) as f32)
        })
        .collect()
}
