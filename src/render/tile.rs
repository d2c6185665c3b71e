//! A rectangle of the image that one render covers (`render --tile`): for images whose outputs
//! do not fit one device, rendered in parts and merged (`noisefree merge`). A pixel's random
//! numbers depend on its place in the whole image (kernels/render/pathtrace.cl), so a tile's
//! pixels are exactly those of the whole render.

use std::fmt;

use anyhow::{Result, bail};
use serde::{Deserialize, Serialize};

/// `width` x `height` pixels with the top-left one at (`x`, `y`) of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Tile {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl Tile {
    /// The whole of a `width` x `height` image.
    pub fn whole(width: u32, height: u32) -> Tile {
        Tile {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// Parses `WxH+X+Y` (the X11 geometry form: 256x256+256+0 is the top-right quarter of a
    /// 512 x 512 image).
    pub fn parse(s: &str) -> std::result::Result<Tile, String> {
        let bad = || format!("expected WxH+X+Y, e.g. 256x256+0+256, got {s:?}");
        let (size, rest) = s.split_once('+').ok_or_else(bad)?;
        let (x, y) = rest.split_once('+').ok_or_else(bad)?;
        let (w, h) = size.split_once('x').ok_or_else(bad)?;
        let n = |t: &str| t.trim().parse::<u32>().map_err(|_| bad());
        let tile = Tile {
            x: n(x)?,
            y: n(y)?,
            width: n(w)?,
            height: n(h)?,
        };
        if tile.width == 0 || tile.height == 0 {
            return Err(format!("{s:?}: a tile is at least 1x1 pixels"));
        }
        Ok(tile)
    }

    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Fails unless the tile lies inside a `width` x `height` image.
    pub fn check_within(&self, width: u32, height: u32) -> Result<()> {
        let fits = |o: u32, l: u32, max: u32| o.checked_add(l).is_some_and(|end| end <= max);
        if self.width == 0
            || self.height == 0
            || !fits(self.x, self.width, width)
            || !fits(self.y, self.height, height)
        {
            bail!("tile {self} does not lie inside the {width}x{height} image");
        }
        Ok(())
    }

    pub fn is_whole(&self, width: u32, height: u32) -> bool {
        *self == Tile::whole(width, height)
    }

    /// The image's pixel index of the tile's pixel `i` (row-major in the tile) in an image
    /// `image_width` wide.
    pub fn image_pixel(&self, i: usize, image_width: u32) -> usize {
        let (tx, ty) = (i % self.width as usize, i / self.width as usize);
        (self.y as usize + ty) * image_width as usize + self.x as usize + tx
    }
}

impl fmt::Display for Tile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}+{}+{}", self.width, self.height, self.x, self.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_prints_and_places_tiles() {
        let t = Tile::parse("3x2+4+1").unwrap();
        assert_eq!(
            t,
            Tile {
                x: 4,
                y: 1,
                width: 3,
                height: 2
            }
        );
        assert_eq!(t.to_string(), "3x2+4+1");
        assert!(t.check_within(7, 3).is_ok());
        assert!(t.check_within(6, 3).is_err());
        assert!(t.check_within(7, 2).is_err());
        // Pixel 4 of the tile is its second row's second pixel: (5, 2) of a 10-wide image.
        assert_eq!(t.image_pixel(4, 10), 2 * 10 + 5);
        for bad in ["3x2", "3x2+4", "0x2+0+0", "ax2+0+0", "3x2+-1+0"] {
            assert!(Tile::parse(bad).is_err(), "{bad}");
        }
        assert!(Tile { x: u32::MAX, ..t }.check_within(7, 3).is_err());
    }
}
