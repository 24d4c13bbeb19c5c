//! The particle pass's back-to-front order: every particle sorted by its depth along an axis,
//! farthest first, ties in pool order, so the order (and so the blended pixels) is
//! deterministic. The axis is the view direction, or with [`SortOrder::HalfAngle`] the
//! half-angle axis that `has` slices along, so that one sort serves the eye and the light
//! (the thesis' chapter 5: "combine HAS with OSMs or DOMs for the purpose of performing only one
//! sort").
//!
//! Each particle gets a `u32` key, `!ordered(depth)`, where `ordered` maps the depth's bits to
//! an unsigned integer in the order of [`f32::total_cmp`], so ascending keys are descending
//! depths. The (key, index) pairs, built in pool order, are sorted by an LSD radix sort
//! (`radsort`, the one bevy sorts its render phases with): stable, so equal depths keep pool
//! order, and single-threaded, so no schedule can change the result. Measured on the 2-core
//! development machine at 1M particles: 12-15 ms against 24-30 ms for rayon's
//! `par_sort_unstable` on `u64` (key, index) and 16-18 ms for `sort_unstable`; 0.3-0.9 ms
//! against 1.4-2 ms at 65,536.

use std::fmt;

use glam::Vec3;
use rayon::prelude::*;

use crate::sim::Particle;

/// The order of the frame's one sort (`--sort`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum SortOrder {
    /// By view depth: exactly back to front for the eye (the default, the thesis' frame).
    #[default]
    View,
    /// Along the half-angle between the view and the light direction ([`Slicing`]), back to
    /// front for the eye along that axis: the order `has` draws and fills its light buffer in,
    /// so it needs no sort of its own, and every other technique builds its maps from the same
    /// sorted particles the eye draws. The eye's order is then approximate where particles
    /// overlap at different depths along the view but not along the axis.
    HalfAngle,
}

impl SortOrder {
    /// Every order, the default first.
    pub const ALL: [SortOrder; 2] = [Self::View, Self::HalfAngle];

    /// As the CLI spells it.
    pub fn name(self) -> &'static str {
        match self {
            Self::View => "view",
            Self::HalfAngle => "half-angle",
        }
    }
}

impl fmt::Display for SortOrder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The axis whose depth the frame sorts by, farthest first, for `order`: the view direction,
/// or the half-angle axis oriented so that farthest along it is farthest from the eye (the
/// slicing, returned with it, says which way the light's order runs).
pub fn depth_axis(order: SortOrder, view_dir: Vec3, light_dir: Vec3) -> (Vec3, Option<Slicing>) {
    match order {
        SortOrder::View => (view_dir, None),
        SortOrder::HalfAngle => {
            let slicing = Slicing::new(view_dir, light_dir);
            // Ascending along the axis is front to back for the eye when the camera looks
            // with the light, back to front when it faces it.
            let axis = if slicing.eye_front_to_back {
                slicing.axis
            } else {
                -slicing.axis
            };
            (axis, Some(slicing))
        }
    }
}

/// From this many particles the keys are computed on rayon's pool (below it the task overhead
/// would be most of the work).
const PARALLEL_FROM: usize = 16 * 1024;

/// Pool indices of `particles` from the farthest to the nearest along `forward` (unit view axis)
/// from `eye`; equal depths keep pool order.
pub fn back_to_front(particles: &[Particle], eye: Vec3, forward: Vec3) -> Vec<u32> {
    let pair =
        |(i, p): (usize, &Particle)| (far_first_key((p.position - eye).dot(forward)), i as u32);
    let mut pairs: Vec<(u32, u32)> = if particles.len() < PARALLEL_FROM {
        particles.iter().enumerate().map(pair).collect()
    } else {
        particles.par_iter().enumerate().map(pair).collect()
    };
    radsort::sort_by_key(&mut pairs, |&(key, _)| key);
    pairs.into_iter().map(|(_, index)| index).collect()
}

/// The sort key of a particle at view depth `depth_m`: ascending keys are descending depths
/// ([`f32::total_cmp`]'s order reversed).
pub fn far_first_key(depth_m: f32) -> u32 {
    !ordered_bits(depth_m)
}

/// The bits of `x` as an unsigned integer that orders like [`f32::total_cmp`]: negative values
/// (sign bit set) have all bits flipped, positive ones only the sign bit.
fn ordered_bits(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// The half-angle slicing axis (`has`, thesis ch. 5; the frame's one sort may share it) and
/// how the eye composites along it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slicing {
    /// Unit half-angle axis; particles are sorted by increasing `dot(p, axis)`, which is front
    /// to back from the light.
    pub axis: Vec3,
    /// True: that order is also front to back for the eye ("under"); false: back to front
    /// ("over", the camera faces the light).
    pub eye_front_to_back: bool,
}

impl Slicing {
    /// The half-angle between the unit view direction and the unit light direction (the way
    /// light travels), inverting the view when the camera faces the light.
    pub fn new(view_dir: Vec3, light_dir: Vec3) -> Self {
        let eye_front_to_back = view_dir.dot(light_dir) >= 0.0;
        let view = if eye_front_to_back {
            view_dir
        } else {
            -view_dir
        };
        let axis = (view + light_dir).try_normalize().unwrap_or(light_dir);
        Self {
            axis,
            eye_front_to_back,
        }
    }

    /// Particle indices sorted along the axis (ties by index, deterministic): the frame's radix
    /// sort, farthest first along the reversed axis.
    pub fn order(&self, particles: &[Particle]) -> Vec<u32> {
        back_to_front(particles, Vec3::ZERO, -self.axis)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn particle_at(z: f32) -> Particle {
        Particle {
            position: Vec3::new(0.0, 0.0, z),
            velocity: Vec3::ZERO,
            age_s: 0.0,
            radius_m: 0.1,
            density_per_m: 1.0,
            albedo: Vec3::ONE,
        }
    }

    /// The comparator the renderer used before the keys: depth descending by `total_cmp`, ties
    /// by index.
    fn reference_order(depths: &[f32]) -> Vec<u32> {
        let mut order: Vec<(f32, u32)> = depths.iter().copied().zip(0..).collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        order.into_iter().map(|(_, i)| i).collect()
    }

    #[test]
    fn keys_order_like_total_cmp_reversed() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for a in specials {
            for b in specials {
                assert_eq!(
                    far_first_key(a).cmp(&far_first_key(b)),
                    b.total_cmp(&a),
                    "{a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn the_half_angle_order_runs_back_to_front_for_the_eye() {
        let view = Vec3::new(0.0, 0.0, -1.0);
        // Light with the view (the eye composites the light's order front to back) and
        // against it (the camera faces the light).
        for light in [Vec3::new(0.6, -0.8, 0.0), Vec3::new(0.6, 0.0, 0.8)] {
            let (axis, slicing) = depth_axis(SortOrder::HalfAngle, view, light);
            let slicing = slicing.unwrap();
            assert_eq!(slicing.eye_front_to_back, view.dot(light) >= 0.0);
            // Farthest first along `axis` is farthest from the eye first: the axis leans
            // into the view.
            assert!(axis.dot(view) > 0.0);
            // Particles strung along the view line come out exactly back to front, and the
            // light's order (ascending along the slicing axis) is that or its reverse.
            let line: Vec<Particle> = (0..50).map(|i| particle_at(-(i as f32) * 0.3)).collect();
            let order = back_to_front(&line, Vec3::ZERO, axis);
            assert_eq!(order, (0..50).rev().collect::<Vec<u32>>());
            let mut light_order = slicing.order(&line);
            if slicing.eye_front_to_back {
                light_order.reverse();
            }
            assert_eq!(light_order, order);
        }
        assert_eq!(depth_axis(SortOrder::View, view, Vec3::X), (view, None));
    }

    #[test]
    fn ties_keep_pool_order() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        // Few distinct values, so that many depths tie.
        let depths: Vec<f32> = (0..5000)
            .map(|_| f32::from(rng.random_range(-40i16..40)) * 0.25)
            .collect();
        let particles: Vec<Particle> = depths.iter().map(|&z| particle_at(z)).collect();
        assert_eq!(
            back_to_front(&particles, Vec3::ZERO, Vec3::Z),
            reference_order(&depths)
        );
    }

    #[test]
    fn serial_and_parallel_paths_agree_with_the_comparator() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(9);
        for n in [
            0,
            1,
            7,
            PARALLEL_FROM - 1,
            PARALLEL_FROM + 3,
            3 * PARALLEL_FROM,
        ] {
            let depths: Vec<f32> = (0..n)
                .map(|_| f32::from(rng.random_range(0u16..500)) * 0.01)
                .collect();
            let particles: Vec<Particle> = depths.iter().map(|&z| particle_at(z)).collect();
            // Camera at the origin looking down +z: view depth = z.
            let order = back_to_front(&particles, Vec3::ZERO, Vec3::Z);
            assert_eq!(order, reference_order(&depths), "{n} particles");
        }
    }
}
