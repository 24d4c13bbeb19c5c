//! A dense density grid in the world, and its exact transmittance on the CPU: the f64 mirror of
//! the volumes' reference (issue 26 §4), a march along the light ray whose step count is shown
//! to have converged rather than assumed (T at N and 2N steps within a tolerance, the number of
//! steps doubled until they are).
//!
//! Conventions are OpenVDB's: voxel (i, j, k) holds the density at its centre, at integer index
//! coordinates; between centres the density is trilinear; outside the grid's voxels (and half a
//! voxel of ramp around them) it is zero. The grid maps index to world by an affine
//! `world_from_index` (the file's transform, then the scene's), and `density_scale_per_m` turns
//! the grid's values into extinction in 1/m.

use glam::{DAffine3, DVec3, UVec3};
use thiserror::Error;

use super::analytic::{HomogeneousMedium, Shape};

/// A dense grid of densities (x fastest, then y, then z) placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGrid {
    /// Voxels along x, y and z.
    pub dims: UVec3,
    /// The density of each voxel, x fastest; extinction is `density_scale_per_m` times it.
    pub values: Vec<f32>,
    /// World metres from index coordinates (voxel (0, 0, 0)'s centre at index (0, 0, 0)).
    pub world_from_index: DAffine3,
    /// Extinction per unit of density, 1/m.
    pub density_scale_per_m: f64,
    /// A homogeneous shape's closed form in index space ([`DensityGrid::voxelize`]): its density
    /// is the shape's, not the voxels' trilinear blend, and its optical depth has a closed form
    /// (`exact`'s). `None` for a file's grid or the cloud's.
    pub analytic: Option<IndexShape>,
}

/// A homogeneous shape in a grid's index space: every density sample of the frame (the eye's
/// march, the builds, `srm`) reads it there, and `exact` takes its chord in closed form, so
/// that the reference and the techniques see one density. The index space is the grid's box
/// scaled per axis, so a sphere is an ellipsoid there and a box stays a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexShape {
    pub kind: IndexShapeKind,
    /// The density inside (extinction is `density_scale_per_m` times it).
    pub density: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IndexShapeKind {
    Ellipsoid { center: DVec3, radii: DVec3 },
    Box { min: DVec3, max: DVec3 },
}

impl IndexShape {
    /// Whether index point `q` is inside (the boundary included).
    pub fn contains(&self, q: DVec3) -> bool {
        match self.kind {
            IndexShapeKind::Ellipsoid { center, radii } => {
                ((q - center) / radii).length_squared() <= 1.0
            }
            IndexShapeKind::Box { min, max } => q.cmpge(min).all() && q.cmple(max).all(),
        }
    }

    /// The fraction of the segment `qa`..`qb` (index space) inside the shape, 0..1.
    pub fn inside_fraction(&self, qa: DVec3, qb: DVec3) -> f64 {
        let chord = match self.kind {
            IndexShapeKind::Ellipsoid { center, radii } => Shape::Sphere {
                center: DVec3::ZERO,
                radius_m: 1.0,
            }
            .chord((qa - center) / radii, (qb - qa) / radii),
            IndexShapeKind::Box { min, max } => Shape::Box { min, max }.chord(qa, qb - qa),
        };
        chord.map_or(0.0, |(t0, t1)| (t1.min(1.0) - t0.max(0.0)).max(0.0))
    }
}

/// Why a transmittance could not be computed to the asked tolerance.
#[derive(Debug, Error, PartialEq)]
pub enum MarchError {
    #[error(
        "the march did not converge: T at {steps} and {} steps differ by {difference:.2e}, more \
         than {tolerance:.0e}",
        2 * steps
    )]
    NotConverged {
        steps: u32,
        difference: f64,
        tolerance: f64,
    },
}

/// Index to world for `dims` voxels filling the box `min`..`max`: each voxel a cell of the box,
/// its centre the cell's middle.
pub fn box_cells(min: DVec3, max: DVec3, dims: UVec3) -> DAffine3 {
    let cell = (max - min) / dims.max(UVec3::ONE).as_dvec3();
    DAffine3::from_translation(min + 0.5 * cell) * DAffine3::from_scale(cell)
}

/// Why a file's grid cannot be a medium.
#[derive(Debug, Error, PartialEq)]
pub enum GridError {
    #[error(
        "grid {name:?} has the background value {background}, not 0: its density would fill \
         all space outside its voxels"
    )]
    Background { name: String, background: f32 },
    #[error("grid {name:?} holds a negative density ({value} at index {index})")]
    Negative {
        name: String,
        value: f32,
        index: glam::IVec3,
    },
    #[error("grid {name:?} holds a density that is not a finite number at index {index}")]
    NotFinite { name: String, index: glam::IVec3 },
}

/// The fewest steps a converged march may take over a support segment `index_length` voxels
/// long: two a voxel. Below that, T at N and at 2N can agree while both step over a feature
/// thinner than the steps (a voxelised ball's edge missed by 8 and by 16 steps reads T = 1 at
/// both), so agreement proves nothing.
pub fn steps_per_voxel_length(index_length: f64) -> u32 {
    (2.0 * index_length)
        .ceil()
        .clamp(1.0, f64::from(u32::MAX / 4)) as u32
}

/// A converged transmittance: T, and the step count N whose T agreed with 2N's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Converged {
    pub transmittance: f64,
    pub steps: u32,
}

impl DensityGrid {
    /// No voxels: nothing anywhere (what the frame binds without a volume).
    pub fn empty() -> Self {
        Self {
            dims: UVec3::ZERO,
            values: Vec::new(),
            world_from_index: DAffine3::IDENTITY,
            density_scale_per_m: 0.0,
            analytic: None,
        }
    }

    /// The voxels of `medium` sampled at the centres of a grid of `dims` voxels spanning the
    /// world box `min`..`max` (each voxel a cell of that box, its centre its sample).
    pub fn voxelize(medium: &HomogeneousMedium, min: DVec3, max: DVec3, dims: UVec3) -> Self {
        let world_from_index = box_cells(min, max, dims);
        let mut values = Vec::with_capacity((dims.x * dims.y * dims.z) as usize);
        for k in 0..dims.z {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    let p = world_from_index.transform_point3(UVec3::new(i, j, k).as_dvec3());
                    values.push(medium.extinction_at(p) as f32);
                }
            }
        }
        // The box's cells are an axis-aligned scaling: a sphere's radius scales per axis.
        let index_from_world = world_from_index.inverse();
        let kind = match medium.shape {
            Shape::Sphere { center, radius_m } => IndexShapeKind::Ellipsoid {
                center: index_from_world.transform_point3(center),
                radii: index_from_world
                    .transform_vector3(DVec3::splat(radius_m))
                    .abs(),
            },
            Shape::Box { min, max } => {
                let (a, b) = (
                    index_from_world.transform_point3(min),
                    index_from_world.transform_point3(max),
                );
                IndexShapeKind::Box {
                    min: a.min(b),
                    max: a.max(b),
                }
            }
        };
        Self {
            dims,
            values,
            world_from_index,
            density_scale_per_m: 1.0,
            analytic: Some(IndexShape {
                kind,
                density: medium.extinction_per_m,
            }),
        }
    }

    /// The medium an OpenVDB float grid describes: its dense voxels placed by the file's
    /// transform (the file's index `index_min` is voxel (0, 0, 0) here), then by `world_from_file`
    /// (the scene's placement), with `density_scale_per_m` of extinction per unit of density.
    /// A density must be finite and not negative, and the background (the density outside the
    /// voxels) zero.
    pub fn from_vdb(
        grid: &super::vdb::FloatGrid,
        world_from_file: DAffine3,
        density_scale_per_m: f64,
    ) -> Result<Self, GridError> {
        if grid.background != 0.0 {
            return Err(GridError::Background {
                name: grid.name.clone(),
                background: grid.background,
            });
        }
        let dims = grid.dims;
        for (n, &value) in grid.values.iter().enumerate() {
            if value.is_finite() && value >= 0.0 {
                continue;
            }
            let n = n as u32;
            let local = UVec3::new(n % dims.x, (n / dims.x) % dims.y, n / (dims.x * dims.y));
            let index = grid.index_min + local.as_ivec3();
            let name = grid.name.clone();
            return Err(match value.is_finite() {
                true => GridError::Negative { name, value, index },
                false => GridError::NotFinite { name, index },
            });
        }
        Ok(Self {
            dims,
            values: grid.values.clone(),
            world_from_index: world_from_file
                * grid.world_from_index
                * DAffine3::from_translation(grid.index_min.as_dvec3()),
            density_scale_per_m,
            analytic: None,
        })
    }

    /// The world box the density can be non-zero in (the voxels and their half-voxel ramp),
    /// as the bounds of its eight corners; `None` for an empty grid.
    pub fn world_bounds(&self) -> Option<(DVec3, DVec3)> {
        if self.dims.min_element() == 0 {
            return None;
        }
        let hi = self.dims.as_dvec3() - DVec3::splat(0.5);
        let corners = (0..8).map(|c| {
            let pick = |bit: u32, v: f64| if c & bit == 0 { -0.5 } else { v };
            self.world_from_index.transform_point3(DVec3::new(
                pick(1, hi.x),
                pick(2, hi.y),
                pick(4, hi.z),
            ))
        });
        let (mut lo, mut up) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in corners {
            lo = lo.min(p);
            up = up.max(p);
        }
        Some((lo, up))
    }

    fn voxel(&self, i: i64, j: i64, k: i64) -> f64 {
        let d = self.dims.as_i64vec3();
        if i < 0 || j < 0 || k < 0 || i >= d.x || j >= d.y || k >= d.z {
            return 0.0;
        }
        f64::from(self.values[(i + d.x * (j + d.y * k)) as usize])
    }

    /// The density at index coordinates `q`: a shape's ([`IndexShape`]), else trilinear
    /// between voxel centres.
    pub fn density_at_index(&self, q: DVec3) -> f64 {
        if let Some(shape) = &self.analytic {
            return if shape.contains(q) {
                shape.density
            } else {
                0.0
            };
        }
        let base = q.floor();
        let f = q - base;
        let (i, j, k) = (base.x as i64, base.y as i64, base.z as i64);
        let mut sum = 0.0;
        for (dk, wz) in [(0, 1.0 - f.z), (1, f.z)] {
            for (dj, wy) in [(0, 1.0 - f.y), (1, f.y)] {
                for (di, wx) in [(0, 1.0 - f.x), (1, f.x)] {
                    let w = wx * wy * wz;
                    if w != 0.0 {
                        sum += w * self.voxel(i + di, j + dj, k + dk);
                    }
                }
            }
        }
        sum
    }

    /// Extinction at world point `p`, 1/m.
    pub fn extinction_at(&self, p: DVec3) -> f64 {
        let q = self.world_from_index.inverse().transform_point3(p);
        self.density_scale_per_m * self.density_at_index(q)
    }

    /// The part [t0, t1] of the segment a + t (b - a), t in [0, 1], where the density can be
    /// non-zero: the voxels' box widened by the trilinear ramp's voxel, in index space.
    pub fn support(&self, a_index: DVec3, b_index: DVec3) -> Option<(f64, f64)> {
        let lo = DVec3::splat(-1.0);
        let hi = self.dims.as_dvec3();
        let d = b_index - a_index;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for axis in 0..3 {
            if d[axis] == 0.0 {
                if a_index[axis] <= lo[axis] || a_index[axis] >= hi[axis] {
                    return None;
                }
                continue;
            }
            let (u, v) = (
                (lo[axis] - a_index[axis]) / d[axis],
                (hi[axis] - a_index[axis]) / d[axis],
            );
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
        (t0 < t1).then_some((t0, t1))
    }

    /// Optical depth from `a` to `b` (world metres) by the midpoint rule with `steps` steps over
    /// the part of the segment where the density can be non-zero.
    pub fn marched_optical_depth(&self, a: DVec3, b: DVec3, steps: u32) -> f64 {
        let index_from_world = self.world_from_index.inverse();
        let (qa, qb) = (
            index_from_world.transform_point3(a),
            index_from_world.transform_point3(b),
        );
        let Some((t0, t1)) = self.support(qa, qb) else {
            return 0.0;
        };
        let steps = steps.max(1);
        let dt = (t1 - t0) / f64::from(steps);
        let sum: f64 = (0..steps)
            .map(|i| self.density_at_index(qa.lerp(qb, t0 + (f64::from(i) + 0.5) * dt)))
            .sum();
        self.density_scale_per_m * sum * dt * (b - a).length()
    }

    /// The eye's march of `shaders/medium/eye_march.wgsl` in f64 (one colour channel): the
    /// radiance scattered towards the eye along `origin + t·dir` (`dir` a unit vector) for t in
    /// [`t_near`, `t_far`], and the ray's transmittance, from `steps` steps over the grid's
    /// support, each sampled at `jitter` (0..1) of its length, with `in_scatter(p)` the source
    /// at p per unit of scattering.
    #[allow(clippy::too_many_arguments)] // the shader function's arguments, one for one
    pub fn march_eye(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_near: f64,
        t_far: f64,
        steps: u32,
        jitter: f64,
        albedo: f64,
        in_scatter: impl Fn(DVec3) -> f64,
    ) -> (f64, f64) {
        let (a, b) = (origin + t_near * dir, origin + t_far * dir);
        let index_from_world = self.world_from_index.inverse();
        let (qa, qb) = (
            index_from_world.transform_point3(a),
            index_from_world.transform_point3(b),
        );
        let (mut radiance, mut transmittance) = (0.0, 1.0);
        let Some((t0, t1)) = self.support(qa, qb) else {
            return (radiance, transmittance);
        };
        if steps == 0 || t_far <= t_near {
            return (radiance, transmittance);
        }
        let dt = (t1 - t0) / f64::from(steps);
        let step_m = dt * (t_far - t_near);
        for i in 0..steps {
            let f = t0 + (f64::from(i) + jitter) * dt;
            let sigma = self.density_scale_per_m * self.density_at_index(qa.lerp(qb, f));
            if sigma <= 0.0 {
                continue;
            }
            let step_t = (-sigma * step_m).exp();
            radiance += transmittance * albedo * in_scatter(a.lerp(b, f)) * (1.0 - step_t);
            transmittance *= step_t;
        }
        (radiance, transmittance)
    }

    /// A shape's optical depth from `a` to `b` (world metres) in closed form: its density times
    /// the length of the segment inside it; `None` for a grid without a shape.
    pub fn closed_form_optical_depth(&self, a: DVec3, b: DVec3) -> Option<f64> {
        let shape = self.analytic?;
        let index_from_world = self.world_from_index.inverse();
        let fraction = shape.inside_fraction(
            index_from_world.transform_point3(a),
            index_from_world.transform_point3(b),
        );
        Some(self.density_scale_per_m * shape.density * fraction * (b - a).length())
    }

    /// Transmittance from `light` to `p`, marched with `start_steps` steps (at least two a voxel
    /// of the segment's support: [`steps_per_voxel_length`]) and then twice as many until two
    /// successive counts agree within `tolerance`, up to `max_steps`.
    pub fn converged_transmittance(
        &self,
        light: DVec3,
        p: DVec3,
        start_steps: u32,
        max_steps: u32,
        tolerance: f64,
    ) -> Result<Converged, MarchError> {
        let index_from_world = self.world_from_index.inverse();
        let (qa, qb) = (
            index_from_world.transform_point3(light),
            index_from_world.transform_point3(p),
        );
        let support = self
            .support(qa, qb)
            .map_or(0.0, |(t0, t1)| (t1 - t0) * (qb - qa).length());
        let mut steps = start_steps.max(steps_per_voxel_length(support));
        let mut t = (-self.marched_optical_depth(light, p, steps)).exp();
        loop {
            let t2 = (-self.marched_optical_depth(light, p, 2 * steps)).exp();
            let difference = (t2 - t).abs();
            if difference <= tolerance {
                return Ok(Converged {
                    transmittance: t2,
                    steps,
                });
            }
            if 2 * steps > max_steps / 2 {
                return Err(MarchError::NotConverged {
                    steps,
                    difference,
                    tolerance,
                });
            }
            steps *= 2;
            t = t2;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::analytic::Shape;

    fn medium(shape: Shape) -> HomogeneousMedium {
        HomogeneousMedium {
            shape,
            extinction_per_m: 0.8,
        }
    }

    #[test]
    fn trilinear_density_is_each_voxel_at_its_centre_and_the_mean_between() {
        let grid = DensityGrid {
            dims: UVec3::new(2, 1, 1),
            values: vec![1.0, 3.0],
            world_from_index: DAffine3::IDENTITY,
            density_scale_per_m: 1.0,
            analytic: None,
        };
        assert_eq!(grid.density_at_index(DVec3::new(0.0, 0.0, 0.0)), 1.0);
        assert_eq!(grid.density_at_index(DVec3::new(1.0, 0.0, 0.0)), 3.0);
        assert_eq!(grid.density_at_index(DVec3::new(0.5, 0.0, 0.0)), 2.0);
        // Half a voxel outside, half of the edge voxel; a voxel outside, nothing.
        assert_eq!(grid.density_at_index(DVec3::new(-0.5, 0.0, 0.0)), 0.5);
        assert_eq!(grid.density_at_index(DVec3::new(-1.0, 0.0, 0.0)), 0.0);
    }

    #[test]
    fn a_voxelized_box_on_cell_boundaries_marches_to_the_closed_form() {
        // The box's faces on the grid's cell boundaries: along an axis, the trilinear ramp
        // across each face integrates to exactly half a voxel either side, so the march
        // converges to σ times the box's width, the analytic box's closed form.
        let box_medium = medium(Shape::Box {
            min: DVec3::new(1.0, 1.0, 1.0),
            max: DVec3::new(3.0, 2.5, 2.0),
        });
        let grid = DensityGrid::voxelize(
            &box_medium,
            DVec3::ZERO,
            DVec3::splat(4.0),
            UVec3::splat(16),
        );
        for (a, b) in [
            (DVec3::new(-5.0, 1.8, 1.4), DVec3::new(9.0, 1.8, 1.4)),
            (DVec3::new(2.2, -3.0, 1.6), DVec3::new(2.2, 7.0, 1.6)),
            (DVec3::new(1.9, 1.3, 8.0), DVec3::new(1.9, 1.3, 1.5)),
        ] {
            let exact = box_medium.transmittance(a, b);
            let marched = grid
                .converged_transmittance(a, b, 16, 1 << 16, 1e-6)
                .unwrap();
            assert!(
                (marched.transmittance - exact).abs() < 1e-4,
                "{a} -> {b}: marched {marched:?}, closed form {exact}"
            );
        }
    }

    #[test]
    fn a_shapes_grid_is_the_shape_itself_in_closed_form_at_any_voxels() {
        // A sphere in a grid of unequal cells (an ellipsoid in index space), and a rotated-free
        // box: their density is the shape's, whatever the voxels, and the closed form of the
        // chord in index space is the world's.
        let ball = medium(Shape::Sphere {
            center: DVec3::splat(2.0),
            radius_m: 1.5,
        });
        let slab = medium(Shape::Box {
            min: DVec3::new(0.7, 1.1, 0.3),
            max: DVec3::new(3.1, 2.5, 4.2),
        });
        let rays = [
            (DVec3::new(-3.0, 2.3, 1.6), DVec3::new(7.0, 2.0, 2.4)),
            (DVec3::new(2.1, 9.0, -4.0), DVec3::new(1.7, -2.0, 5.5)),
            (DVec3::new(2.0, 2.0, 2.0), DVec3::new(9.0, 8.0, 7.0)),
            (DVec3::new(-1.0, 3.4, 0.2), DVec3::new(5.0, 3.4, 0.2)),
        ];
        for shape in [ball, slab] {
            for dims in [UVec3::splat(8), UVec3::new(8, 32, 128)] {
                let grid =
                    DensityGrid::voxelize(&shape, DVec3::ZERO, DVec3::new(4.0, 4.0, 5.0), dims);
                for (a, b) in rays {
                    let exact = shape.optical_depth(a, b);
                    let closed = grid.closed_form_optical_depth(a, b).unwrap();
                    assert!(
                        (closed - exact).abs() <= 1e-9 * exact.max(1.0),
                        "{shape:?} {dims}: {a} -> {b}: {closed} against {exact}"
                    );
                    let marched = grid.marched_optical_depth(a, b, 1 << 14);
                    assert!(
                        (marched - exact).abs() <= 2e-3 * exact.max(0.01),
                        "{shape:?} {dims}: {a} -> {b}: marched {marched} against {exact}"
                    );
                }
                for p in [
                    DVec3::splat(2.0),
                    DVec3::new(3.0, 1.2, 4.0),
                    DVec3::new(0.1, 0.1, 0.1),
                ] {
                    assert_eq!(grid.extinction_at(p), shape.extinction_at(p), "{p}");
                }
            }
        }
    }

    #[test]
    fn the_march_refuses_to_claim_convergence_it_did_not_reach() {
        // Trilinear density along a diagonal ray is cubic between the voxel planes it crosses,
        // so a few midpoint steps cannot agree to 1e-12.
        let grid = DensityGrid {
            dims: UVec3::splat(2),
            values: (1..=8).map(|v| v as f32).collect(),
            world_from_index: DAffine3::from_scale(DVec3::splat(0.01)),
            density_scale_per_m: 50.0,
            analytic: None,
        };
        let (a, b) = (
            DVec3::new(-0.013, -0.009, -0.011),
            DVec3::new(0.022, 0.019, 0.024),
        );
        let err = grid.converged_transmittance(a, b, 1, 8, 1e-12).unwrap_err();
        assert!(matches!(err, MarchError::NotConverged { .. }), "{err}");
        // An empty segment converges at once to 1.
        let far = grid.converged_transmittance(DVec3::splat(5.0), DVec3::splat(6.0), 1, 8, 1e-12);
        assert_eq!(far.unwrap().transmittance, 1.0);
    }
}
