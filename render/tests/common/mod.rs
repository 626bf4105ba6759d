//! Small synthetic scenes written into a fresh temporary folder.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A fresh, empty temporary folder, removed when the returned guard is dropped.
pub fn temp_dir(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-render-test-{tag}-")).tempdir().unwrap()
}

/// A 4 × 2.5 × 4 room (x, y, z) seen from inside, parts floor / walls / ceiling, with a box on
/// the floor (part "crate"). With `uvs` false the OBJ has no `vt`.
pub fn room_obj(uvs: bool) -> String {
    let mut s = String::from("mtllib room.mtl\n");
    let quads: [(&str, [[f32; 3]; 4]); 7] = [
        ("floor", [[0.0, 0.0, 0.0], [0.0, 0.0, 4.0], [4.0, 0.0, 4.0], [4.0, 0.0, 0.0]]),
        ("ceiling", [[0.0, 2.5, 0.0], [4.0, 2.5, 0.0], [4.0, 2.5, 4.0], [0.0, 2.5, 4.0]]),
        ("walls", [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [4.0, 2.5, 0.0], [0.0, 2.5, 0.0]]),
        ("walls", [[0.0, 0.0, 4.0], [0.0, 2.5, 4.0], [4.0, 2.5, 4.0], [4.0, 0.0, 4.0]]),
        ("walls", [[0.0, 0.0, 0.0], [0.0, 2.5, 0.0], [0.0, 2.5, 4.0], [0.0, 0.0, 4.0]]),
        ("walls", [[4.0, 0.0, 0.0], [4.0, 0.0, 4.0], [4.0, 2.5, 4.0], [4.0, 2.5, 0.0]]),
        ("crate", [[1.5, 0.5, 1.5], [1.5, 0.5, 2.5], [2.5, 0.5, 2.5], [2.5, 0.5, 1.5]]),
    ];
    let mut v = 0;
    let mut current = "";
    for (name, q) in quads {
        for p in q {
            s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        if uvs {
            s += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
        }
        if name != current {
            s += &format!("usemtl {name}\n");
            current = name;
        }
        let f = |i: usize| if uvs { format!("{}/{}", v + i, v + i) } else { format!("{}", v + i) };
        s += &format!("f {} {} {} {}\n", f(1), f(2), f(3), f(4));
        v += 4;
    }
    s
}

pub const MTL: &str = "newmtl floor\nKd 0.5 0.4 0.3\nnewmtl ceiling\nKd 0.8 0.8 0.8\nnewmtl walls\nKd 0.6 0.6 0.6\nnewmtl crate\nKd 0.3 0.5 0.2\n";

/// Emits downwards (−y) from just below the ceiling.
pub const LIGHT_OBJ: &str =
    "v 1.5 2.49 1.5\nv 2.5 2.49 1.5\nv 2.5 2.49 2.5\nv 1.5 2.49 2.5\nvn 0 -1 0\nf 1//1 2//1 3//1 4//1\n";

pub const W: usize = 40;
pub const H: usize = 30;

/// The scene.json of the test room, with a `{CAMERA}` and `{LABELS}` placeholder replaced.
pub fn manifest(camera: &str, part_labels: &str) -> String {
    format!(
        r#"{{
  "format": "photoscene-scene/1",
  "units": "meters",
  "up": [0, 1, 0],
  "mesh": "room.obj",
  "views": [
    {{
      "name": "view0",
      "image": "views/view0.png",
      "camera": {camera},
      "parts": "views/view0_parts.png",
      "part_labels": {part_labels}
    }}
  ],
  "lights": [ {{ "name": "lamp", "mesh": "lights/lamp.obj" }} ]
}}"#
    )
}

pub const GOOD_CAMERA: &str =
    r#"{ "position": [2.0, 1.4, 3.8], "look_at": [2.0, 0.8, 1.0], "up": [0, 1, 0], "fov_y_deg": 60.0 }"#;
pub const GOOD_LABELS: &str = r#"{ "1": "floor", "2": "walls", "3": "crate" }"#;

/// Write a complete, valid scene; tests then break one thing.
pub fn write_scene(dir: &Path) {
    std::fs::create_dir_all(dir.join("views")).unwrap();
    std::fs::create_dir_all(dir.join("lights")).unwrap();
    std::fs::write(dir.join("room.obj"), room_obj(true)).unwrap();
    std::fs::write(dir.join("room.mtl"), MTL).unwrap();
    std::fs::write(dir.join("lights/lamp.obj"), LIGHT_OBJ).unwrap();
    std::fs::write(dir.join("scene.json"), manifest(GOOD_CAMERA, GOOD_LABELS)).unwrap();
    psc_render::image_io::write_rgb(&dir.join("views/view0.png"), W, H, &vec![[0.5; 3]; W * H]).unwrap();
    write_labels(dir, W, H);
}

pub fn write_labels(dir: &Path, w: usize, h: usize) {
    let labels: Vec<u16> = (0..w * h).map(|i| if i / w > h / 2 { 1 } else { 2 }).collect();
    psc_render::image_io::write_gray16(&dir.join("views/view0_parts.png"), w, h, &labels).unwrap();
}

/// The dev scene `name`, from shared/ beside the checkout (CI layout). When it is absent the
/// test cannot run: outside CI that is said loudly on stderr and the caller skips (None); with
/// the environment variable `CI` set (CI always has the scenes) it is a failure.
pub fn dev_scene(name: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes").join(name);
    if p.join("scene.json").is_file() {
        return Some(p);
    }
    let msg = format!("dev scene {} not found", p.display());
    if std::env::var_os("CI").is_some() {
        panic!("{msg}: CI must have shared/scenes beside the checkout");
    }
    eprintln!("\n*** TEST NOT RUN: {msg}; this test checked nothing (set up shared/scenes to run it) ***\n");
    None
}

/// CRC-32 (PNG's), bitwise.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

/// A PNG file: the signature, an IHDR for `w`×`h` at `bit_depth` and `color_type`, then
/// `chunks` (kind, data) and IEND, each with its CRC.
pub fn png_from_chunks(w: u32, h: u32, bit_depth: u8, color_type: u8, chunks: &[(&[u8; 4], &[u8])]) -> Vec<u8> {
    png_file(w, h, [bit_depth, color_type, 0], chunks)
}

/// `png_from_chunks` with the IHDR's bit depth, colour type and interlace method.
fn png_file(w: u32, h: u32, format: [u8; 3], chunks: &[(&[u8; 4], &[u8])]) -> Vec<u8> {
    let [bit_depth, color_type, interlace] = format;
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[bit_depth, color_type, 0, 0, interlace]);
    chunk(b"IHDR", &ihdr);
    for (kind, data) in chunks {
        chunk(&kind[..], data);
    }
    chunk(b"IEND", &[]);
    out
}

/// A PNG of any colour type and bit depth the encoders here do not write (palette, 1/2/4-bit
/// grayscale): `rows` are the packed scanlines, `plte` the palette (RGB triples) if any. The
/// image data is zlib with stored (uncompressed) blocks.
pub fn png_bytes(w: u32, h: u32, bit_depth: u8, color_type: u8, plte: Option<&[u8]>, rows: &[Vec<u8>]) -> Vec<u8> {
    png_of_rows(w, h, [bit_depth, color_type, 0], plte, rows)
}

/// `png_bytes` with the interlace method too (`rows`: the scanlines of every pass, in order).
fn png_of_rows(w: u32, h: u32, format: [u8; 3], plte: Option<&[u8]>, rows: &[Vec<u8>]) -> Vec<u8> {
    let raw: Vec<u8> = rows.iter().flat_map(|r| std::iter::once(0u8).chain(r.iter().copied())).collect();
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
    for (i, b) in blocks.iter().enumerate() {
        z.push(u8::from(i + 1 == blocks.len()));
        z.extend_from_slice(&(b.len() as u16).to_le_bytes());
        z.extend_from_slice(&(!(b.len() as u16)).to_le_bytes());
        z.extend_from_slice(b);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in &raw {
        a = (a + x as u32) % 65_521;
        b = (b + a) % 65_521;
    }
    z.extend_from_slice(&((b << 16) | a).to_be_bytes());
    let mut chunks: Vec<(&[u8; 4], &[u8])> = plte.map(|p| (b"PLTE", p)).into_iter().collect();
    chunks.push((b"IDAT", &z));
    png_file(w, h, format, &chunks)
}

/// One scanline of `values` at `bit_depth` (1, 2, 4 or 8): packed most significant bit first,
/// the last byte padded with zero bits.
pub fn pack_row(values: &[u8], bit_depth: u8) -> Vec<u8> {
    let per_byte = 8 / bit_depth as usize;
    values
        .chunks(per_byte)
        .map(|c| c.iter().enumerate().fold(0u8, |acc, (i, &v)| acc | v << (8 - bit_depth as usize * (i + 1))))
        .collect()
}

/// `png_bytes` for an Adam7-interlaced image of `pixels` (row-major, `w` wide, one value per
/// pixel, packed at `bit_depth`).
pub fn interlaced_png_bytes(
    w: usize,
    h: usize,
    bit_depth: u8,
    color_type: u8,
    plte: Option<&[u8]>,
    pixels: &[u8],
) -> Vec<u8> {
    // (x0, y0, dx, dy) of the seven passes; a pass without columns has no scanlines at all.
    const PASSES: [(usize, usize, usize, usize); 7] =
        [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)];
    let mut rows = Vec::new();
    for (x0, y0, dx, dy) in PASSES {
        if x0 >= w {
            continue;
        }
        for y in (y0..h).step_by(dy) {
            let values: Vec<u8> = (x0..w).step_by(dx).map(|x| pixels[y * w + x]).collect();
            rows.push(pack_row(&values, bit_depth));
        }
    }
    png_of_rows(w as u32, h as u32, [bit_depth, color_type, 1], plte, &rows)
}
