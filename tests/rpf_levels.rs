//! RPF's instruction-set paths (generic, popcnt, AVX-512; `rpf::cpu`) give the same bytes as
//! each other, and the fast neighbourhood selection the same N as the plain transcription of
//! Alg. 6, on synthetic sample sets with edges in every feature, clipped boxes at the image
//! border, sample counts that are not multiples of the vector widths, and extreme values.
//! On a CPU without AVX-512 only the paths it has are compared.

use noisefree::filters::rpf::cpu::Level;
use noisefree::filters::rpf::preprocess::{OffsetTable, PixelRng};
use noisefree::filters::rpf::select::{
    FeatureLine, SelectScratch, Selection, select, select_plain,
};
use noisefree::filters::rpf::{self, RpfSettings, SampleSet};
use noisefree::layout::SampleVector;

/// SplitMix64 to [0, 1).
fn uniform(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// Two surfaces split by a diagonal edge (different normals, depths and textures), a noisy
/// texture on one of them, light that depends on the bounce direction, and a band of "sky"
/// (far world positions, zero normals) along the top.
fn scene(w: u32, h: u32, spp: u32, seed: u64) -> SampleSet {
    let mut st = seed;
    let mut samples = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for _ in 0..spp {
                let (jx, jy) = (uniform(&mut st), uniform(&mut st));
                let (u, v) = (uniform(&mut st), uniform(&mut st));
                let dir = [
                    uniform(&mut st) - 0.5,
                    uniform(&mut st) - 0.5,
                    uniform(&mut st),
                ];
                let (px, py) = (x as f32 + jx, y as f32 + jy);
                let front = px > py * 1.3;
                let sky = y < 2;
                let depth = if front { 5.0 } else { 9.0 + 0.1 * px };
                let texture = if front {
                    [0.7, 0.2 + 0.2 * uniform(&mut st), 0.1]
                } else {
                    [0.3, 0.3, 0.6]
                };
                let light = if dir[2] > 0.6 { 4.0 } else { 0.2 };
                let mut s = SampleVector {
                    position: [px, py],
                    random: [u, v, 0.0, dir[0], dir[1], dir[2]],
                    world1: [0.01 * px * depth, 0.01 * py * depth, depth],
                    normal1: if front {
                        [0.0, 0.0, 1.0]
                    } else {
                        [0.6, 0.0, 0.8]
                    },
                    world2: [px + dir[0] * 3.0, py + dir[1] * 3.0, depth - 2.0 * dir[2]],
                    normal2: [-dir[0], -dir[1], 0.5],
                    texture1: texture,
                    color: texture.map(|t| t * light),
                };
                if sky {
                    s.world1 = dir.map(|d| d * 1.0e9);
                    s.normal1 = [0.0; 3];
                    s.world2 = [0.0; 3];
                    s.normal2 = [0.0; 3];
                    s.texture1 = [0.0; 3];
                    s.color = [0.5, 0.7, 1.0];
                }
                samples.push(s);
            }
        }
    }
    SampleSet::new(w, h, spp, samples).unwrap()
}

fn bytes(image: &noisefree::imaging::RgbImage) -> Vec<u32> {
    image
        .pixels
        .iter()
        .flat_map(|p| p.map(f32::to_bits))
        .collect()
}

#[test]
fn every_instruction_set_gives_the_same_bytes() {
    let levels = Level::available();
    let mut cases = vec![
        ("23x19 at 3 spp", scene(23, 19, 3, 1), vec![17, 7]),
        ("30x26 at 8 spp", scene(30, 26, 8, 2), vec![35, 17, 7]),
        ("12x10 at 11 spp", scene(12, 10, 11, 3), vec![9, 3]),
    ];
    let mut extreme = scene(16, 12, 4, 4);
    for (i, s) in extreme.samples.iter_mut().enumerate() {
        match i % 9 {
            0 => s.color = [3.0e38, 1.0e-38, 0.0],
            1 => s.world1 = [-3.0e38, 3.0e38, 0.0],
            2 => s.normal2 = [1.0e30, -1.0e30, 0.0],
            _ => {}
        }
    }
    cases.push(("extreme values", extreme, vec![9, 5]));
    for (what, set, boxes) in &cases {
        let settings = RpfSettings {
            box_sizes: boxes.clone(),
            ..Default::default()
        };
        let outputs: Vec<Vec<u32>> = levels
            .iter()
            .map(|&level| {
                let out = rpf::filter_at_level(set, &settings, level, &|_| {}).unwrap();
                bytes(&out.image)
            })
            .collect();
        for (level, out) in levels.iter().zip(&outputs) {
            assert!(
                out == &outputs[0],
                "{what}: {level:?} differs from {:?}",
                levels[0]
            );
        }
    }
    eprintln!("compared {levels:?}");
}

#[test]
fn the_fast_selection_is_the_plain_one() {
    let set = scene(41, 37, 5, 9);
    let lines: Vec<FeatureLine> = set.samples.iter().map(FeatureLine::of).collect();
    // 71: a table of more than 64 offsets, drawn by the batched stream (draws.rs `Stream`).
    for b in [71, 55, 17, 7, 2] {
        let table = OffsetTable::new(b);
        let sel = Selection {
            samples: &set.samples,
            lines: &lines,
            width: set.width,
            height: set.height,
            spp: set.spp,
            table: &table,
            draws: (b * b * set.spp / 2) as usize - set.spp as usize,
            kappa_world: 30.0,
            kappa_other: 3.0,
            floor: 0.1,
        };
        let mut scratch = SelectScratch::default();
        let (mut visited, mut plain, mut fast) = (Vec::new(), Vec::new(), Vec::new());
        let mut sizes = 0;
        for y in (0..set.height).step_by(3) {
            for x in 0..set.width {
                let pixel = (y * set.width + x) as u64;
                select_plain(
                    &sel,
                    x,
                    y,
                    &mut PixelRng::new(5, pixel, 1),
                    &mut visited,
                    &mut plain,
                );
                for &level in &Level::available() {
                    let mut rng = PixelRng::new(5, pixel, 1);
                    select(&sel, level, x, y, &mut rng, &mut scratch, &mut fast);
                    assert_eq!(fast, plain, "box {b}, pixel ({x}, {y}), {level:?}");
                }
                sizes += plain.len();
            }
        }
        // Not a test of nothing: the neighbourhoods of the larger boxes hold more than the
        // pixels' own samples.
        let own = (set.width as usize) * (set.height as usize).div_ceil(3) * set.spp as usize;
        if b >= 7 {
            assert!(
                sizes > 2 * own,
                "box {b}: {sizes} samples in N over {own} own"
            );
        }
    }
}
