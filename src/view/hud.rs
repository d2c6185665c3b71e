//! The heads-up lines drawn over the image: text with ab_glyph in the DejaVu Sans the charts
//! use (src/bench/fonts), on a darkened band so that it reads over any image.

use ab_glyph::{Font as _, FontRef, PxScale, ScaleFont as _, point};

const FONT_BYTES: &[u8] = include_bytes!("../bench/fonts/DejaVuSans.ttf");
/// Text height in pixels.
const SIZE: f32 = 13.0;
const LINE: usize = 16;

/// Text drawing into a window's 0RGB pixels.
pub struct Hud {
    font: FontRef<'static>,
}

impl Default for Hud {
    fn default() -> Hud {
        Hud {
            // The embedded font is a valid TrueType file (the charts load it too).
            font: FontRef::try_from_slice(FONT_BYTES).expect("the embedded DejaVu Sans parses"),
        }
    }
}

impl Hud {
    /// Draws `lines` from the top of a `width`-pixel-wide 0RGB image, each on a band that
    /// halves the brightness under it.
    pub fn draw(&self, pixels: &mut [u32], width: usize, lines: &[String]) {
        let height = pixels.len() / width.max(1);
        for (i, text) in lines.iter().enumerate() {
            let top = i * LINE;
            if top + LINE > height {
                break;
            }
            for p in &mut pixels[top * width..(top + LINE) * width] {
                *p = (*p >> 1) & 0x7f7f7f;
            }
            self.text(pixels, width, 4.0, (top + LINE - 4) as f32, text);
        }
    }

    /// White text with its baseline at `baseline`, clipped to the image.
    fn text(&self, pixels: &mut [u32], width: usize, x: f32, baseline: f32, text: &str) {
        let height = pixels.len() / width.max(1);
        let scaled = self.font.as_scaled(PxScale::from(SIZE));
        let mut caret = x;
        let mut previous = None;
        for c in text.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = previous {
                caret += scaled.kern(p, id);
            }
            previous = Some(id);
            let glyph = id.with_scale_and_position(SIZE, point(caret, baseline));
            caret += scaled.h_advance(id);
            let Some(outline) = self.font.outline_glyph(glyph) else {
                continue;
            };
            let b = outline.px_bounds();
            outline.draw(|gx, gy, coverage| {
                let (px, py) = (b.min.x as i64 + gx as i64, b.min.y as i64 + gy as i64);
                if px < 0 || py < 0 || px as usize >= width || py as usize >= height {
                    return;
                }
                let p = &mut pixels[py as usize * width + px as usize];
                let a = coverage.clamp(0.0, 1.0);
                let blend = |shift: u32| {
                    let c = ((*p >> shift) & 0xff) as f32;
                    ((c + (255.0 - c) * a) as u32) << shift
                };
                *p = blend(16) | blend(8) | blend(0);
            });
            if caret > width as f32 {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_lightens_its_line_and_the_band_darkens_the_rest_of_it() {
        let (w, h) = (200usize, 40usize);
        let mut px = vec![0x00808080u32; w * h];
        Hud::default().draw(&mut px, w, &["fps 12.3 | 4 spp".to_string()]);
        let line = &px[..LINE * w];
        assert!(
            line.iter().any(|p| (p & 0xff) > 0xf0),
            "white text on the first line"
        );
        assert!(
            line.contains(&0x00404040),
            "the band halves the image under it"
        );
        assert!(
            px[LINE * w..].iter().all(|p| *p == 0x00808080),
            "below the line: untouched"
        );
    }
}
