//! The texel buffer the kernels read (kernels/render/textures.cl): each texture's texels in one
//! shared buffer of `Float4`s, linear floats, or, for an 8-bit image, its four 8-bit codes per
//! texel, four texels per `Float4`, decoded by two 256-entry tables at the start of the buffer.
//!
//! Why (issue 14): a 256² texture of floats is 1 MiB, so the bundled Cornell boxes' four
//! textures overflow a core's L2 cache and a bilinear lookup waits on the L3; as codes they take
//! a quarter. The tables hold exactly the floats the loader makes of each code
//! ([`crate::scene::texture::srgb8_tables`]), and a texture is stored as codes only when every
//! one of its floats is found in them, so a lookup returns the same floats either way (the
//! images are the same bytes).

use std::collections::HashMap;

use crate::layout::{Float2, Float4, TextureInfo};
use crate::scene::texture::{Texture, srgb8_tables};

/// `TextureInfo::format`: one linear `Float4` per texel.
pub const TEXTURE_LINEAR: u32 = 0;
/// `TextureInfo::format`: one u32 of 8-bit codes (r | g << 8 | b << 16 | a << 24) per texel.
pub const TEXTURE_SRGB8: u32 = 1;
/// `Float4`s at the start of the buffer holding the decode tables when any texture is stored
/// as codes: 256 colour values, then 256 alpha values.
pub const SRGB8_TABLE_SLOTS: usize = 128;

/// Builds the texel buffer and each texture's place and format in it.
pub fn pack(textures: &[Texture]) -> (Vec<Float4>, Vec<TextureInfo>) {
    let (rgb, alpha) = srgb8_tables();
    let inverse = |table: &[f32; 256]| -> HashMap<u32, u32> {
        // Codes in decreasing order so that equal floats keep the smallest code.
        (0..256u32)
            .rev()
            .map(|c| (table[c as usize].to_bits(), c))
            .collect()
    };
    let (inv_rgb, inv_alpha) = (inverse(&rgb), inverse(&alpha));
    let codes: Vec<Option<Vec<u32>>> = textures
        .iter()
        .map(|t| {
            t.texels
                .iter()
                .map(|p| {
                    let c = |v: f32| inv_rgb.get(&v.to_bits()).copied();
                    Some(
                        c(p[0])?
                            | c(p[1])? << 8
                            | c(p[2])? << 16
                            | inv_alpha.get(&p[3].to_bits()).copied()? << 24,
                    )
                })
                .collect()
        })
        .collect();
    let mut texels = Vec::new();
    if codes.iter().any(Option::is_some) {
        let table: Vec<f32> = rgb.iter().chain(alpha.iter()).copied().collect();
        texels.extend(table.chunks(4).map(|c| Float4([c[0], c[1], c[2], c[3]])));
        debug_assert_eq!(texels.len(), SRGB8_TABLE_SLOTS);
    }
    let mut infos = Vec::new();
    for (t, codes) in textures.iter().zip(&codes) {
        let offset = texels.len() as u32;
        let format = match codes {
            Some(words) => {
                texels.extend(words.chunks(4).map(|w| {
                    let f = |i: usize| f32::from_bits(w.get(i).copied().unwrap_or(0));
                    Float4([f(0), f(1), f(2), f(3)])
                }));
                TEXTURE_SRGB8
            }
            None => {
                texels.extend(t.texels.iter().map(|c| Float4(*c)));
                TEXTURE_LINEAR
            }
        };
        infos.push(TextureInfo {
            offset,
            width: t.width,
            height: t.height,
            format,
            uv_scale: Float2::from_vec2(t.uv_scale),
            uv_shift: Float2::from_vec2(t.uv_shift),
        });
    }
    (texels, infos)
}

/// Texel `index` (row-major) of the texture `t` in the buffer `texels`, decoded as the kernels
/// decode it.
pub fn texel(texels: &[Float4], t: &TextureInfo, index: u32) -> [f32; 4] {
    if t.format == TEXTURE_SRGB8 {
        let slot = texels[(t.offset + index / 4) as usize].0;
        let word = slot[(index % 4) as usize].to_bits();
        let table = |i: u32| {
            let i = i as usize;
            texels[i / 4].0[i % 4]
        };
        [
            table(word & 0xff),
            table((word >> 8) & 0xff),
            table((word >> 16) & 0xff),
            table(256 + (word >> 24)),
        ]
    } else {
        texels[(t.offset + index) as usize].0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    fn texture(texels: Vec<[f32; 4]>, width: u32) -> Texture {
        Texture {
            name: "t".into(),
            width,
            height: texels.len() as u32 / width,
            texels,
            uv_scale: Vec2::ONE,
            uv_shift: Vec2::ZERO,
        }
    }

    #[test]
    fn codes_decode_to_the_loaders_floats_and_others_stay_floats() {
        let (rgb, alpha) = srgb8_tables();
        // Five texels (a partial last slot) of decodable floats, and one texture that is not.
        let eight: Vec<[f32; 4]> = (0..5)
            .map(|i| [rgb[i * 50], rgb[255 - i], rgb[7 * i], alpha[200 + i]])
            .collect();
        let float = vec![[0.123_456_7, 0.5, 1.0, 1.0], [2.0, 0.0, 0.0, 1.0]];
        let textures = [texture(eight.clone(), 5), texture(float.clone(), 2)];
        let (texels, infos) = pack(&textures);
        assert_eq!(infos[0].format, TEXTURE_SRGB8);
        assert_eq!(infos[1].format, TEXTURE_LINEAR);
        assert_eq!(infos[0].offset as usize, SRGB8_TABLE_SLOTS);
        assert_eq!(infos[1].offset as usize, SRGB8_TABLE_SLOTS + 2);
        for (t, want) in [(&infos[0], &eight), (&infos[1], &float)] {
            for (i, w) in want.iter().enumerate() {
                let got = texel(&texels, t, i as u32);
                assert_eq!(got.map(f32::to_bits), w.map(f32::to_bits), "texel {i}");
            }
        }
        // The bundled 8-bit PNG textures are stored as codes, the float EXR sky as floats.
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/textures");
        let loaded: Vec<Texture> = ["wood.png", "sky.exr"]
            .iter()
            .map(|f| {
                let (w, _, t) = crate::scene::texture::load_image(&dir.join(f)).unwrap();
                texture(t, w)
            })
            .collect();
        let (_, infos) = pack(&loaded);
        assert_eq!(
            (infos[0].format, infos[1].format),
            (TEXTURE_SRGB8, TEXTURE_LINEAR)
        );
        // Without 8-bit textures there are no tables.
        let (texels, infos) = pack(&textures[1..]);
        assert_eq!((texels.len(), infos[0].offset), (2, 0));
    }
}
