//! Small raster helpers shared by pictures and plots: bitmap text and PNG encoding.

use std::path::Path;

use font8x8::UnicodeFonts;

use super::write_atomic;
use crate::error::Result;

/// Writes `text` into RGB rows of `width` x `height` pixels in an 8x16 bitmap font (8x8
/// glyphs, rows doubled), with its top-left corner at `at`; clipped at the right edge.
pub fn text(
    rgb: &mut [u8],
    width: usize,
    height: usize,
    at: (usize, usize),
    text: &str,
    col: [u8; 3],
) {
    let (mut cx, y) = at;
    for ch in text.chars() {
        let glyph = font8x8::BASIC_FONTS
            .get(ch)
            .or_else(|| font8x8::BASIC_FONTS.get('?'));
        if let Some(rows) = glyph {
            for (r, bits) in rows.iter().enumerate() {
                for c in 0..8 {
                    if bits & (1 << c) != 0 {
                        let (px, py) = (cx + c, y + r * 2);
                        for dy in 0..2 {
                            if px < width && py + dy < height {
                                let i = (py + dy) * width + px;
                                rgb[i * 3..i * 3 + 3].copy_from_slice(&col);
                            }
                        }
                    }
                }
            }
        }
        cx += 9;
        if cx + 8 >= width {
            break;
        }
    }
}

/// Width in pixels of `text` as [`text`] draws it.
pub fn text_width(text: &str) -> usize {
    text.chars().count() * 9
}

/// Encodes RGB rows as PNG into `path` (through a temporary file).
pub fn write_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    write_atomic(path, |w| {
        let mut enc = png::Encoder::new(w, width as u32, height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(rgb)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    })
}
