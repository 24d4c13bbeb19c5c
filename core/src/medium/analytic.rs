//! Analytic media: a homogeneous sphere and a homogeneous box, whose transmittance along any
//! ray has a closed form (Beer–Lambert over the ray's chord through the shape). They are the
//! volumes' "single spherical particle" (pbrt's habit of analytic cases first): the exact
//! reference for volumes, every technique's volume build and the eye's ray march are checked
//! against them before they are trusted with a cloud or a simulation's grid.
//!
//! Everything here is f64 on the CPU: the mirror the GPU's march is held to.
//!
//! The next analytic medium (a slab, a cylinder) is one more [`Shape`] variant with its chord.

use glam::DVec3;

/// The shape a homogeneous medium fills.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A ball of `radius_m` around `center`.
    Sphere { center: DVec3, radius_m: f64 },
    /// An axis-aligned box from `min` to `max` (world metres, `min < max` on every axis).
    Box { min: DVec3, max: DVec3 },
}

/// A medium of constant extinction inside its shape and none outside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomogeneousMedium {
    pub shape: Shape,
    /// Extinction coefficient σ_t inside the shape, 1/m.
    pub extinction_per_m: f64,
}

impl Shape {
    /// The parameter interval [t0, t1] (t0 <= t1) along `origin + t·dir` that lies inside the
    /// shape, or `None` when the line misses it. `dir` need not be normalised; the interval is
    /// in units of `dir`'s length.
    pub fn chord(&self, origin: DVec3, dir: DVec3) -> Option<(f64, f64)> {
        match *self {
            Shape::Sphere { center, radius_m } => {
                // |o + t d - c|² = r²: a t² + 2 b t + c = 0.
                let oc = origin - center;
                let a = dir.length_squared();
                if a == 0.0 {
                    return None;
                }
                let b = oc.dot(dir);
                let c = oc.length_squared() - radius_m * radius_m;
                let disc = b * b - a * c;
                if disc <= 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                Some(((-b - root) / a, (-b + root) / a))
            }
            Shape::Box { min, max } => {
                // Slabs: the intersection of the three axis intervals.
                let mut t0 = f64::NEG_INFINITY;
                let mut t1 = f64::INFINITY;
                for axis in 0..3 {
                    let (o, d, lo, hi) = (origin[axis], dir[axis], min[axis], max[axis]);
                    if d == 0.0 {
                        if o < lo || o > hi {
                            return None;
                        }
                        continue;
                    }
                    let (a, b) = ((lo - o) / d, (hi - o) / d);
                    t0 = t0.max(a.min(b));
                    t1 = t1.min(a.max(b));
                }
                (t0 < t1).then_some((t0, t1))
            }
        }
    }

    /// The shape's axis-aligned bounds (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        match *self {
            Shape::Sphere { center, radius_m } => (
                center - DVec3::splat(radius_m),
                center + DVec3::splat(radius_m),
            ),
            Shape::Box { min, max } => (min, max),
        }
    }

    /// Whether `p` lies inside the shape (its boundary included).
    pub fn contains(&self, p: DVec3) -> bool {
        match *self {
            Shape::Sphere { center, radius_m } => {
                (p - center).length_squared() <= radius_m * radius_m
            }
            Shape::Box { min, max } => p.cmpge(min).all() && p.cmple(max).all(),
        }
    }
}

impl HomogeneousMedium {
    /// Extinction at `p`, 1/m: σ_t inside the shape, 0 outside.
    pub fn extinction_at(&self, p: DVec3) -> f64 {
        match self.shape.contains(p) {
            true => self.extinction_per_m,
            false => 0.0,
        }
    }

    /// Optical depth τ of the segment from `a` to `b`: σ_t times the length of the segment
    /// that lies inside the shape.
    pub fn optical_depth(&self, a: DVec3, b: DVec3) -> f64 {
        let Some((t0, t1)) = self.shape.chord(a, b - a) else {
            return 0.0;
        };
        let inside = (t1.min(1.0) - t0.max(0.0)).max(0.0);
        self.extinction_per_m * inside * (b - a).length()
    }

    /// Transmittance exp(-τ) of the light from `light` to `p`.
    pub fn transmittance(&self, light: DVec3, p: DVec3) -> f64 {
        (-self.optical_depth(light, p)).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SIGMA: f64 = 0.7;

    fn sphere() -> HomogeneousMedium {
        HomogeneousMedium {
            shape: Shape::Sphere {
                center: DVec3::new(1.0, 2.0, -0.5),
                radius_m: 1.5,
            },
            extinction_per_m: SIGMA,
        }
    }

    fn unit_box() -> HomogeneousMedium {
        HomogeneousMedium {
            shape: Shape::Box {
                min: DVec3::ZERO,
                max: DVec3::ONE,
            },
            extinction_per_m: SIGMA,
        }
    }

    #[test]
    fn a_ray_through_the_sphere_centre_crosses_its_diameter() {
        let m = sphere();
        let light = DVec3::new(1.0, 2.0, 10.0);
        // Behind the sphere: the whole diameter 2r; at the centre: r; in front: nothing.
        let behind = DVec3::new(1.0, 2.0, -5.0);
        let centre = DVec3::new(1.0, 2.0, -0.5);
        let front = DVec3::new(1.0, 2.0, 3.0);
        assert!((m.transmittance(light, behind) - (-SIGMA * 3.0f64).exp()).abs() < 1e-12);
        assert!((m.transmittance(light, centre) - (-SIGMA * 1.5f64).exp()).abs() < 1e-12);
        assert_eq!(m.transmittance(light, front), 1.0);
    }

    #[test]
    fn an_off_centre_ray_crosses_the_sphere_along_its_chord() {
        // A ray at distance d from the centre crosses a chord of 2·sqrt(r² - d²).
        let m = sphere();
        let (r, d) = (1.5f64, 0.9f64);
        let light = DVec3::new(1.0 + d, 2.0, 10.0);
        let p = DVec3::new(1.0 + d, 2.0, -10.0);
        let expected = (-SIGMA * 2.0 * (r * r - d * d).sqrt()).exp();
        assert!((m.transmittance(light, p) - expected).abs() < 1e-12);
        // A ray that passes the sphere by is not dimmed.
        let miss = DVec3::new(1.0 + 1.6, 2.0, 10.0);
        assert_eq!(m.transmittance(miss, miss - DVec3::Z * 20.0), 1.0);
    }

    #[test]
    fn a_ray_through_the_box_crosses_its_width_and_its_diagonal() {
        let m = unit_box();
        // Along x through the middle: width 1.
        let t = m.transmittance(DVec3::new(-3.0, 0.5, 0.5), DVec3::new(4.0, 0.5, 0.5));
        assert!((t - (-SIGMA).exp()).abs() < 1e-12);
        // Corner to corner: the diagonal sqrt(3).
        let t = m.transmittance(DVec3::splat(-1.0), DVec3::splat(2.0));
        assert!((t - (-SIGMA * 3.0f64.sqrt()).exp()).abs() < 1e-12);
        // Ending inside, a quarter of the way along x: 0.25.
        let t = m.transmittance(DVec3::new(-3.0, 0.5, 0.5), DVec3::new(0.25, 0.5, 0.5));
        assert!((t - (-SIGMA * 0.25).exp()).abs() < 1e-12);
        // Parallel to a face, outside it: no chord.
        assert_eq!(
            m.transmittance(DVec3::new(-3.0, 1.5, 0.5), DVec3::new(4.0, 1.5, 0.5)),
            1.0
        );
    }

    /// The midpoint rule over `extinction_at`, the march a volume reference takes.
    fn marched_optical_depth(m: &HomogeneousMedium, a: DVec3, b: DVec3, steps: u32) -> f64 {
        let dt = (b - a).length() / f64::from(steps);
        (0..steps)
            .map(|i| m.extinction_at(a + (b - a) * ((f64::from(i) + 0.5) / f64::from(steps))) * dt)
            .sum()
    }

    #[test]
    fn a_march_of_the_density_converges_to_the_closed_form() {
        // The march's error is at most one step's worth of σ at each of the chord's two ends,
        // so it shrinks at least as 1/N: 2σ·(|b - a|/N) bounds it.
        let sphere_ray = (DVec3::new(-4.0, 2.3, -0.2), DVec3::new(5.0, 1.6, -0.9));
        let box_ray = (DVec3::new(-4.0, 0.3, 0.2), DVec3::new(5.0, 0.8, 0.6));
        for (m, (a, b)) in [(sphere(), sphere_ray), (unit_box(), box_ray)] {
            let exact = m.optical_depth(a, b);
            assert!(exact > 0.5, "the test ray must cross the medium ({exact})");
            let mut last_error = f64::INFINITY;
            for steps in [16, 64, 256, 1024, 4096] {
                let error = (marched_optical_depth(&m, a, b, steps) - exact).abs();
                let bound = 2.0 * SIGMA * (b - a).length() / f64::from(steps);
                assert!(
                    error <= bound,
                    "{steps} steps: error {error} > bound {bound}"
                );
                last_error = last_error.min(error);
            }
            assert!(last_error < 1e-2, "{last_error}");
        }
    }
}
