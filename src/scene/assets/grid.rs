//! `grid`: a square lattice of bars, the occluder of the AAF "Grids" scene (Wang 2013
//! Fig. 3.5a: stacked grids over a plane, whose penumbrae overlap). The unit square in the xz
//! plane (−0.5..0.5), 0.02 thick (y from −0.01 to 0.01), with 8 × 8 square holes between 9 bars
//! each way, each bar 0.04 wide. Bars that cross overlap (two boxes; nothing is shaded inside).

use glam::Vec3;

use super::builder::{PartBuilder, Xf, diffuse};
use crate::scene::mesh::MeshPart;

/// Holes per side.
pub const HOLES: usize = 8;
/// Bar width and plate thickness, in units of the grid's side.
pub const BAR: f32 = 0.04;
pub const THICKNESS: f32 = 0.02;

pub fn grid() -> MeshPart {
    let mut b = PartBuilder::new("grid", diffuse("grid", [0.7, 0.7, 0.7]));
    let (h, t) = (0.5f32, 0.5 * THICKNESS);
    for i in 0..=HOLES {
        // Bar centres from −0.5 + BAR/2 to 0.5 − BAR/2, evenly spaced.
        let c = -h + 0.5 * BAR + i as f32 * (1.0 - BAR) / HOLES as f32;
        let (lo, hi) = (c - 0.5 * BAR, c + 0.5 * BAR);
        b.cuboid(&Xf::IDENTITY, Vec3::new(lo, -t, -h), Vec3::new(hi, t, h));
        b.cuboid(&Xf::IDENTITY, Vec3::new(-h, -t, lo), Vec3::new(h, t, hi));
    }
    b.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_is_two_boxes_per_bar_line_inside_the_unit_square() {
        let g = grid();
        assert_eq!(g.indices.len(), 2 * (HOLES + 1) * 12);
        for p in &g.positions {
            assert!(p.x.abs() <= 0.5 + 1e-6 && p.z.abs() <= 0.5 + 1e-6);
            assert!(p.y.abs() <= 0.5 * THICKNESS + 1e-6);
        }
    }
}
