//! GPU tests of the density grid (`smokeshadow::medium`): the GPU's fixed-step march against
//! the f64 mirror at the same steps, its converged T against the analytic box's closed form,
//! the loop-budget refusal, the empty grid, and the bytes it counts. They run on lavapipe and
//! fail, never skip, without one.

use smokeshadow::Wait;
#[path = "medium/cloud_noise.rs"]
mod cloud_noise;
mod common;

use common::gpu;
use glam::{DAffine3, DQuat, DVec3, UVec3, Vec3};
use smokeshadow::gpu::MemoryLedger;
use smokeshadow::medium::analytic::{HomogeneousMedium, Shape};
use smokeshadow::medium::gpu_grid::{Convergence, GpuGrid, GridGpuError, GridMarch};
use smokeshadow::medium::grid::DensityGrid;

/// Points on a lattice around and inside the grid's box `min..max` (world metres).
fn lattice(world_from_index: DAffine3, dims: UVec3) -> Vec<Vec3> {
    let mut points = Vec::new();
    for k in 0..7 {
        for j in 0..7 {
            for i in 0..7 {
                // From a voxel before the grid to a voxel past it, off the voxel centres.
                let f = DVec3::new(i as f64, j as f64, k as f64) / 6.0;
                let q = -DVec3::splat(1.3) + f * (dims.as_dvec3() + DVec3::splat(1.9));
                points.push(world_from_index.transform_point3(q).as_vec3());
            }
        }
    }
    points
}

/// `grid`'s voxels as a file's grid would hold them: the trilinear field, without the shape's
/// closed form that a scene's `shape` samples instead (hard-edged, which a march converges to
/// only as 1/N). These tests hold the march itself, on a smooth field.
fn trilinear(mut grid: DensityGrid) -> DensityGrid {
    grid.analytic = None;
    grid
}

/// A voxelised ball (its trilinear voxels), turned and moved off the axes so that every
/// index-to-world term is used.
fn turned_ball() -> DensityGrid {
    let ball = HomogeneousMedium {
        shape: Shape::Sphere {
            center: DVec3::splat(1.0),
            radius_m: 0.8,
        },
        extinction_per_m: 2.5,
    };
    let mut grid = trilinear(DensityGrid::voxelize(
        &ball,
        DVec3::ZERO,
        DVec3::splat(2.0),
        UVec3::new(24, 20, 28),
    ));
    let placement = DAffine3::from_scale_rotation_translation(
        DVec3::new(1.5, 1.5, 1.5),
        DQuat::from_euler(glam::EulerRot::YXZ, 0.4, -0.3, 0.2),
        DVec3::new(-3.0, 2.0, 5.0),
    );
    grid.world_from_index = placement * grid.world_from_index;
    grid
}

#[test]
fn the_gpu_march_matches_the_f64_mirror_at_the_same_steps() {
    let gpu = gpu();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let march = GridMarch::new(&gpu);
    let grid = turned_ball();
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
    let light = Vec3::new(4.0, 9.0, -2.0);
    let points = lattice(grid.world_from_index, grid.dims);
    for steps in [7, 64, 512] {
        let t_gpu = march
            .transmittance(&gpu, &uploaded, light, &points, steps)
            .wait()
            .unwrap();
        let mut dimmed = 0;
        for (p, t) in points.iter().zip(&t_gpu) {
            let t_cpu = (-grid.marched_optical_depth(light.as_dvec3(), p.as_dvec3(), steps)).exp();
            // f32 against f64 over at most 512 steps of densities O(1): the sums agree to
            // ~1e-6 relative; 1e-4 in T leaves room for the f32 index transform.
            assert!(
                (f64::from(*t) - t_cpu).abs() < 1e-4,
                "{steps} steps at {p}: GPU {t}, CPU {t_cpu}"
            );
            dimmed += usize::from(t_cpu < 0.9);
        }
        assert!(
            dimmed > 20,
            "the lattice must sample the shadow ({dimmed} points dimmed)"
        );
    }
}

#[test]
fn the_converged_gpu_march_reaches_the_analytic_boxs_closed_form() {
    // The box's faces on the grid's cell boundaries: the trilinear ramps integrate to the
    // box's width exactly (core/src/medium/grid.rs), so the converged march is the closed form.
    let gpu = gpu();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let march = GridMarch::new(&gpu);
    let slab = HomogeneousMedium {
        shape: Shape::Box {
            min: DVec3::new(0.5, 0.25, 0.75),
            max: DVec3::new(1.5, 1.75, 1.25),
        },
        extinction_per_m: 1.2,
    };
    let grid = trilinear(DensityGrid::voxelize(
        &slab,
        DVec3::ZERO,
        DVec3::splat(2.0),
        UVec3::splat(32),
    ));
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
    // A light far above: its rays run almost along z. The points keep a voxel and a half from
    // the box's sides in x and y and away from its top and bottom faces' half-voxel ramps in z
    // (a point inside a ramp sees part of it, which the sharp box does not have).
    let light = Vec3::new(1.0, 1.0, 1000.0);
    let heights = [1.6, 1.3, 1.15, 1.0, 0.8, 0.6, 0.2, -0.3];
    let points: Vec<Vec3> = (0..40)
        .map(|i| {
            let f = i as f32 / 39.0;
            let z = heights[i % heights.len()];
            Vec3::new(0.6 + 0.8 * f, 0.35 + 1.3 * (1.0 - f), z)
        })
        .collect();
    let (n, n2) = (2048, 4096);
    let t_n = march
        .transmittance(&gpu, &uploaded, light, &points, n)
        .wait()
        .unwrap();
    let t_2n = march
        .transmittance(&gpu, &uploaded, light, &points, n2)
        .wait()
        .unwrap();
    for ((p, a), b) in points.iter().zip(&t_n).zip(&t_2n) {
        assert!((a - b).abs() < 1e-4, "{p}: {n} steps {a}, {n2} steps {b}");
        let exact = slab.transmittance(light.as_dvec3(), p.as_dvec3());
        assert!(
            (f64::from(*b) - exact).abs() < 1e-4,
            "{p}: marched {b}, closed form {exact}"
        );
    }
    // Some points lie in the box's shadow, some in it, some above it.
    let exact: Vec<f64> = points
        .iter()
        .map(|p| slab.transmittance(light.as_dvec3(), p.as_dvec3()))
        .collect();
    assert!(exact.contains(&1.0) && exact.iter().any(|t| *t < 0.6));
}

#[test]
fn an_empty_grid_casts_no_shadow_and_its_bytes_are_counted() {
    let gpu = gpu();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let march = GridMarch::new(&gpu);
    let empty = DensityGrid {
        dims: UVec3::ZERO,
        values: Vec::new(),
        world_from_index: DAffine3::IDENTITY,
        density_scale_per_m: 1.0,
        analytic: None,
    };
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &empty).unwrap();
    let t = march
        .transmittance(
            &gpu,
            &uploaded,
            Vec3::splat(5.0),
            &[Vec3::ZERO, Vec3::ONE],
            64,
        )
        .wait()
        .unwrap();
    assert_eq!(t, vec![1.0, 1.0]);
    // One placeholder voxel (4 bytes) and the 160-byte uniform (the placement, 96 bytes, the
    // frame's march settings, 32, and a shape's closed form, 32).
    assert_eq!(uploaded.bytes, 4 + 160);
    let grid = turned_ball();
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
    assert_eq!(uploaded.bytes, 24 * 20 * 28 * 4 + 160);
    // A shape is sampled in closed form: one placeholder voxel, whatever its grid's size.
    let mut shape = grid;
    shape.analytic = DensityGrid::voxelize(
        &HomogeneousMedium {
            shape: Shape::Sphere {
                center: DVec3::splat(1.0),
                radius_m: 0.8,
            },
            extinction_per_m: 2.5,
        },
        DVec3::ZERO,
        DVec3::splat(2.0),
        UVec3::new(24, 20, 28),
    )
    .analytic;
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &shape).unwrap();
    assert_eq!(uploaded.bytes, 4 + 160);
    assert_eq!(
        uploaded.dims,
        UVec3::new(24, 20, 28),
        "its box still bounds the marches"
    );
}

#[test]
fn a_march_longer_than_the_loop_budget_is_refused_where_there_is_one() {
    let gpu = gpu();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let march = GridMarch::new(&gpu);
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &turned_ball()).unwrap();
    let result = march.transmittance(&gpu, &uploaded, Vec3::splat(5.0), &[Vec3::ZERO], 100_000);
    match gpu.loop_budget() {
        Some(budget) => {
            let err = result.wait().unwrap_err();
            assert!(matches!(err, GridGpuError::TooManySteps { .. }), "{err}");
            assert!(err.to_string().contains(&budget.to_string()), "{err}");
        }
        None => assert_eq!(result.wait().unwrap().len(), 1),
    }
}

#[test]
fn the_gpu_cloud_noise_is_the_cpu_mirrors_texel_for_texel() {
    use smokeshadow::medium::cloud::CloudNoiseGenerator;
    use smokeshadow::medium::cloud_noise::{DETAIL_SIZE, SHAPE_SIZE, detail_voxel, shape_voxel};
    let gpu = gpu();
    let generator = CloudNoiseGenerator::new(&gpu);
    for seed in [1, 0xdecafbad] {
        let (shape, detail) = generator.read_texels(&gpu, seed).wait().unwrap();
        assert_eq!(shape.len(), (SHAPE_SIZE.pow(3) * 4) as usize);
        assert_eq!(detail.len(), (DETAIL_SIZE.pow(3) * 4) as usize);
        // The mirror's texels at a lattice of voxels (every texel would take the debug-built
        // CPU minutes), corners and faces included, where tiling bugs would show. Integer
        // lattice and hash are exact on both; the last bits of sqrt, division and fused
        // multiply-adds differ by ~1e-6 on values of order 1.
        let mut worst: f32 = 0.0;
        let coords = |size: u32| [0, 1, size / 3, size / 2 + 1, size - 2, size - 1];
        for z in coords(SHAPE_SIZE) {
            for y in coords(SHAPE_SIZE) {
                for x in coords(SHAPE_SIZE) {
                    let at = (((z * SHAPE_SIZE + y) * SHAPE_SIZE + x) * 4) as usize;
                    for (c, cpu) in shape_voxel(seed, x, y, z).iter().enumerate() {
                        worst = worst.max((shape[at + c] - cpu).abs());
                    }
                }
            }
        }
        for z in coords(DETAIL_SIZE) {
            for y in coords(DETAIL_SIZE) {
                for x in coords(DETAIL_SIZE) {
                    let at = (((z * DETAIL_SIZE + y) * DETAIL_SIZE + x) * 4) as usize;
                    for (c, cpu) in detail_voxel(seed, x, y, z).iter().enumerate() {
                        worst = worst.max((detail[at + c] - cpu).abs());
                    }
                    assert_eq!(detail[at + 3], 0.0);
                }
            }
        }
        assert!(
            worst < 1e-5,
            "seed {seed}: GPU and CPU texels differ by {worst}"
        );
        // Not a constant: the texels spread over most of 0..1.
        let (lo, hi) = shape
            .iter()
            .fold((1.0f32, 0.0f32), |(l, h), v| (l.min(*v), h.max(*v)));
        assert!(lo < 0.2 && hi > 0.9, "shape texels span {lo}..{hi}");
    }
}

mod eye {
    use super::*;
    use smokeshadow::medium::eye::{EyeMarchProbe, EyeMarchSettings, EyeRay};

    /// Rays along +x through the slab's interior, from well before it to well past it.
    fn rays_through(min: DVec3, max: DVec3) -> Vec<EyeRay> {
        (0..24)
            .map(|i| {
                let f = (i as f64 + 0.5) / 24.0;
                let y = min.y + (max.y - min.y) * (0.1 + 0.8 * f);
                let z = min.z + (max.z - min.z) * (0.9 - 0.8 * f);
                EyeRay {
                    origin: Vec3::new(-4.0, y as f32, z as f32),
                    dir: Vec3::X,
                    t_near: 0.5 + i as f32 * 0.1,
                    t_far: 12.0,
                }
            })
            .collect()
    }

    #[test]
    fn with_a_constant_source_the_march_is_albedo_times_one_minus_t_at_any_step_count() {
        // With the light's transmittance 1 everywhere (no light steps) the source is 1, and the
        // march's sum telescopes to albedo · (1 - T) exactly (shaders/medium/eye_march.wgsl);
        // converged, T is the box's closed form exp(-σ·width).
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let probe = EyeMarchProbe::new(&gpu);
        let (min, max) = (DVec3::new(0.5, 0.25, 0.75), DVec3::new(1.5, 1.75, 1.25));
        let slab = HomogeneousMedium {
            shape: Shape::Box { min, max },
            extinction_per_m: 1.7,
        };
        let grid = trilinear(DensityGrid::voxelize(
            &slab,
            DVec3::ZERO,
            DVec3::splat(2.0),
            UVec3::splat(32),
        ));
        let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
        let rays = rays_through(min, max);
        let albedo = Vec3::new(0.9, 0.6, 0.3);
        let exact_t = (-1.7f64 * 1.0).exp();
        for (steps, jitter) in [(5, 0.5), (37, 0.13), (4000, 0.5)] {
            let settings = EyeMarchSettings {
                light: Vec3::new(1.0, 9.0, 1.0),
                albedo,
                eye_steps: steps,
                light_steps: 0,
                jitter,
            };
            let results = probe
                .march(&gpu, &uploaded, &settings, &rays)
                .wait()
                .unwrap();
            for (ray, r) in rays.iter().zip(&results) {
                let expected = albedo * (1.0 - r.transmittance);
                assert!(
                    (r.radiance - expected).abs().max_element() < 1e-5,
                    "{steps} steps, {ray:?}: {r:?}, albedo·(1 - T) = {expected}"
                );
                // 4000 steps converge to the reference's 1e-4 (f32 products of 4000 step
                // transmittances lose ~1e-6).
                if steps == 4000 {
                    let t = f64::from(r.transmittance);
                    assert!(
                        (t - exact_t).abs() < 1e-4,
                        "{ray:?}: T {t}, closed form {exact_t}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_shadowed_march_matches_the_f64_mirror() {
        // Secondary ray marching towards the light from every eye sample, on the turned ball:
        // the shader against DensityGrid::march_eye at the same steps and jitter.
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let probe = EyeMarchProbe::new(&gpu);
        let grid = turned_ball();
        let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
        let (lo, hi) = grid.world_bounds().unwrap();
        let centre = (0.5 * (lo + hi)).as_vec3();
        let eye = centre + Vec3::new(0.5, 1.0, -9.0);
        let rays: Vec<EyeRay> = (0..48)
            .map(|i| {
                let (u, v) = ((i % 8) as f32 / 7.0 - 0.5, (i / 8) as f32 / 5.0 - 0.5);
                let target = centre + Vec3::new(u * 3.5, v * 3.5, 0.0);
                EyeRay {
                    origin: eye,
                    dir: (target - eye).normalize(),
                    t_near: 0.1,
                    t_far: 20.0,
                }
            })
            .collect();
        let settings = EyeMarchSettings {
            light: centre + Vec3::new(-6.0, 7.0, 2.0),
            albedo: Vec3::splat(0.8),
            eye_steps: 48,
            light_steps: 32,
            jitter: 0.37,
        };
        let results = probe
            .march(&gpu, &uploaded, &settings, &rays)
            .wait()
            .unwrap();
        let mut lit_and_dense = 0;
        for (ray, r) in rays.iter().zip(&results) {
            let (radiance, t) = grid.march_eye(
                ray.origin.as_dvec3(),
                ray.dir.as_dvec3(),
                f64::from(ray.t_near),
                f64::from(ray.t_far),
                settings.eye_steps,
                f64::from(settings.jitter),
                0.8,
                |p| (-grid.marched_optical_depth(settings.light.as_dvec3(), p, 32)).exp(),
            );
            assert!(
                (f64::from(r.transmittance) - t).abs() < 1e-4,
                "{ray:?}: {r:?} vs T {t}"
            );
            assert!(
                (f64::from(r.radiance.x) - radiance).abs() < 1e-4,
                "{ray:?}: {r:?} vs {radiance}"
            );
            // Self-shadowing: the radiance is below the unshadowed albedo · (1 - T).
            assert!(radiance <= 0.8 * (1.0 - t) + 1e-12);
            lit_and_dense += usize::from(t < 0.5 && radiance < 0.8 * (1.0 - t) * 0.9);
        }
        assert!(
            lit_and_dense >= 4,
            "the ball must shadow itself on some rays ({lit_and_dense})"
        );
    }

    #[test]
    fn a_march_just_within_the_loop_budget_is_marched_whole() {
        // llvmpipe cuts an invocation's loops short once they have looped 65,535 times in all
        // and carries on with what it has. The probe accepts what its bound says fits in the
        // loop budget (60,000): marches right at that bound must come out as the f64 mirror's.
        // (With a loop the bound did not count, the box lookup's over three axes, these read T
        // up to 0.07 off.)
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let probe = EyeMarchProbe::new(&gpu);
        let medium = HomogeneousMedium {
            shape: Shape::Box {
                min: DVec3::splat(-1.0),
                max: DVec3::splat(3.0),
            },
            extinction_per_m: 0.3,
        };
        let grid = trilinear(DensityGrid::voxelize(
            &medium,
            DVec3::ZERO,
            DVec3::splat(2.0),
            UVec3::splat(16),
        ));
        let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
        // Every ray ends inside the grid's box, so every eye step has density.
        let rays: Vec<EyeRay> = (0..16)
            .map(|i| EyeRay {
                origin: Vec3::new(-4.0, 0.3 + 0.09 * i as f32, 1.0),
                dir: Vec3::X,
                t_near: 0.5,
                t_far: 5.0,
            })
            .collect();
        let light = Vec3::new(1.0, 9.0, 1.0);
        // Eye steps x (light steps + 4) + 3 just under 60,000: the probe's own bound.
        for (eye_steps, light_steps, allowed) in [(14_999u32, 0u32, 1e-3), (2_999, 16, 2e-4)] {
            let settings = EyeMarchSettings {
                light,
                albedo: Vec3::ONE,
                eye_steps,
                light_steps,
                jitter: 0.5,
            };
            let results = match probe.march(&gpu, &uploaded, &settings, &rays).wait() {
                Ok(results) => results,
                Err(e) => panic!("{eye_steps} x {light_steps} steps refused: {e}"),
            };
            for (ray, r) in rays.iter().zip(&results) {
                let (_, t) = grid.march_eye(
                    ray.origin.as_dvec3(),
                    ray.dir.as_dvec3(),
                    f64::from(ray.t_near),
                    f64::from(ray.t_far),
                    eye_steps,
                    0.5,
                    1.0,
                    |p| {
                        if light_steps == 0 {
                            1.0
                        } else {
                            (-grid.marched_optical_depth(light.as_dvec3(), p, light_steps)).exp()
                        }
                    },
                );
                let dt = (f64::from(r.transmittance) - t).abs();
                assert!(
                    dt < allowed,
                    "{eye_steps} x {light_steps} steps, {ray:?}: T {} against the mirror's {t}",
                    r.transmittance
                );
            }
        }
    }

    #[test]
    fn a_march_past_the_loop_budget_is_refused_where_there_is_one() {
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let probe = EyeMarchProbe::new(&gpu);
        let uploaded = GpuGrid::upload(&gpu, &mut ledger, &turned_ball()).unwrap();
        let settings = EyeMarchSettings {
            light: Vec3::splat(5.0),
            albedo: Vec3::ONE,
            eye_steps: 512,
            light_steps: 512,
            jitter: 0.5,
        };
        let ray = EyeRay {
            origin: Vec3::splat(-5.0),
            dir: Vec3::ONE.normalize(),
            t_near: 0.0,
            t_far: 30.0,
        };
        let result = probe.march(&gpu, &uploaded, &settings, &[ray]).wait();
        match gpu.loop_budget() {
            Some(_) => assert!(result.is_err(), "512 x 512 steps must be refused"),
            None => assert_eq!(result.unwrap().len(), 1),
        }
    }
}

mod cloud {
    use super::*;
    use smokeshadow::medium::cloud::{CloudBaker, CloudNoiseGenerator, bake_voxel_centre};
    use smokeshadow::medium::cloud_noise::{CloudParams, baked_density};

    const SEED: u32 = 2026;
    const DIMS: UVec3 = UVec3::new(40, 20, 40);

    fn layer(coverage: f32) -> CloudParams {
        CloudParams {
            origin_xz_m: [-2000.0, -2000.0],
            size_xz_m: [4000.0, 4000.0],
            altitude_m: 1500.0,
            thickness_m: 1200.0,
            coverage,
            density_per_m: 0.05,
            top_fraction: 1.0,
            shape_period_m: 3000.0,
            detail_period_m: 700.0,
            coverage_map: 0.0,
        }
    }

    #[test]
    fn the_baked_cloud_is_the_mirrors_density_and_grows_with_coverage() {
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let noise = CloudNoiseGenerator::new(&gpu)
            .generate(&gpu, &mut ledger, SEED)
            .unwrap();
        let baker = CloudBaker::new(&gpu);
        let mut cloudy_fractions = Vec::new();
        for coverage in [0.0, 0.3, 0.6, 0.9] {
            let params = layer(coverage);
            let grid = baker
                .bake(&gpu, &mut ledger, &noise, &params, DIMS, glam::Vec3::ZERO)
                .wait()
                .unwrap();
            assert_eq!(grid.values.len(), (DIMS.x * DIMS.y * DIMS.z) as usize);
            // The mirror at a lattice of voxels: the same integer lattice and hash, the same
            // f32 operations; 1e-4 of the layer's densest extinction covers the last bits of
            // sqrt, division and fused multiply-adds through the remaps' gains.
            let mut worst: f32 = 0.0;
            for k in (0..DIMS.z).step_by(7) {
                for j in (0..DIMS.y).step_by(3) {
                    for i in (0..DIMS.x).step_by(7) {
                        let index = UVec3::new(i, j, k);
                        let p = bake_voxel_centre(&params, DIMS, index);
                        let cpu = baked_density(SEED, p, &params);
                        let n = ((k * DIMS.y + j) * DIMS.x + i) as usize;
                        worst = worst.max((grid.values[n] - cpu).abs());
                    }
                }
            }
            assert!(
                worst < 1e-4 * params.density_per_m,
                "coverage {coverage}: {worst}"
            );
            assert!(
                grid.values
                    .iter()
                    .all(|v| (0.0..=params.density_per_m).contains(v))
            );
            // The bottom voxel layer is nearly empty (the density height gradient starts at 0).
            let bottom_max = grid
                .values
                .chunks(DIMS.x as usize)
                .step_by(DIMS.y as usize)
                .flatten()
                .fold(0.0f32, |m, v| m.max(*v));
            assert!(
                bottom_max < 0.05 * params.density_per_m,
                "bottom layer: {bottom_max}"
            );
            let cloudy = grid.values.iter().filter(|v| **v > 0.0).count();
            cloudy_fractions.push(cloudy as f64 / grid.values.len() as f64);
        }
        assert_eq!(cloudy_fractions[0], 0.0, "no coverage, no cloud");
        assert!(
            cloudy_fractions.windows(2).all(|w| w[1] > w[0]),
            "more coverage, more cloud: {cloudy_fractions:?}"
        );
        assert!(cloudy_fractions[3] > 0.3, "{cloudy_fractions:?}");
    }
}

#[test]
fn the_gpu_reference_doubles_its_steps_until_they_converge_or_says_it_could_not() {
    let gpu = gpu();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let march = GridMarch::new(&gpu);
    let grid = turned_ball();
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &grid).unwrap();
    let light = Vec3::new(4.0, 9.0, -2.0);
    let points = lattice(grid.world_from_index, grid.dims);
    let converged = march
        .converged_transmittance(
            &gpu,
            &uploaded,
            light,
            &points,
            Convergence {
                start_steps: 8,
                max_steps: 1 << 16,
                tolerance: 1e-4,
            },
        )
        .wait()
        .unwrap();
    assert!(converged.worst_difference <= 1e-4);
    // At least two steps a voxel along the grid's diagonal, whatever the start asked for: 8
    // and 16 steps both step over the ball's edge on some rays and agree on T = 1 there.
    let diagonal = (grid.dims.as_vec3() + Vec3::ONE).length();
    assert!(
        converged.steps as f32 >= 2.0 * diagonal,
        "{}",
        converged.steps
    );
    for (p, t) in points.iter().zip(&converged.transmittance) {
        let cpu = grid
            .converged_transmittance(light.as_dvec3(), p.as_dvec3(), 8, 1 << 16, 1e-5)
            .unwrap();
        // Both within 1e-4 of their limit, and of each other to twice that.
        assert!(
            (f64::from(*t) - cpu.transmittance).abs() < 2e-4,
            "{p}: {t} vs {cpu:?}"
        );
    }
    // A tolerance no step count reaches in f32: refused in one line that says how far it got.
    let err = march
        .converged_transmittance(
            &gpu,
            &uploaded,
            light,
            &points,
            Convergence {
                start_steps: 8,
                max_steps: 4096,
                tolerance: 1e-9,
            },
        )
        .wait()
        .unwrap_err();
    let line = err.to_string();
    assert!(
        line.contains("did not converge") && !line.contains('\n'),
        "{line}"
    );
}

mod coverage_map {
    use super::*;
    use smokeshadow::medium::cloud::{CloudBaker, CloudNoiseGenerator, bake_voxel_centre};
    use smokeshadow::medium::cloud_noise::{CloudParams, baked_density};

    #[test]
    fn the_coverage_map_parts_the_layer_into_cloud_and_clear_sky() {
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let seed = 11;
        let noise = CloudNoiseGenerator::new(&gpu)
            .generate(&gpu, &mut ledger, seed)
            .unwrap();
        let dims = UVec3::new(48, 16, 48);
        let params = CloudParams {
            origin_xz_m: [0.0, 0.0],
            size_xz_m: [8000.0, 8000.0],
            altitude_m: 1000.0,
            thickness_m: 1000.0,
            coverage: 0.8,
            density_per_m: 0.04,
            top_fraction: 1.0,
            shape_period_m: 3000.0,
            detail_period_m: 600.0,
            coverage_map: 1.0,
        };
        let grid = CloudBaker::new(&gpu)
            .bake(&gpu, &mut ledger, &noise, &params, dims, glam::Vec3::ZERO)
            .wait()
            .unwrap();
        // The mirror, map included, at a lattice of voxels (tolerance as for the bake without
        // the map).
        for k in (0..dims.z).step_by(5) {
            for j in (0..dims.y).step_by(3) {
                for i in (0..dims.x).step_by(5) {
                    let index = UVec3::new(i, j, k);
                    let cpu = baked_density(seed, bake_voxel_centre(&params, dims, index), &params);
                    let gpu_value = grid.values[((k * dims.y + j) * dims.x + i) as usize];
                    assert!(
                        (gpu_value - cpu).abs() < 1e-4 * params.density_per_m,
                        "{index}: GPU {gpu_value}, CPU {cpu}"
                    );
                }
            }
        }
        // Columns (x, z) with no cloud at any height, and columns with cloud: both common. With
        // the map off, the same coverage clouds nearly every column.
        let columns = |values: &[f32]| {
            let mut clear = 0;
            for k in 0..dims.z {
                for i in 0..dims.x {
                    let empty = (0..dims.y)
                        .all(|j| values[((k * dims.y + j) * dims.x + i) as usize] == 0.0);
                    clear += usize::from(empty);
                }
            }
            clear as f64 / f64::from(dims.x * dims.z)
        };
        let clear_with_map = columns(&grid.values);
        assert!(
            (0.15..0.85).contains(&clear_with_map),
            "{clear_with_map} of the columns are clear"
        );
        let unmapped = CloudParams {
            coverage_map: 0.0,
            ..params
        };
        let without = CloudBaker::new(&gpu)
            .bake(&gpu, &mut ledger, &noise, &unmapped, dims, glam::Vec3::ZERO)
            .wait()
            .unwrap();
        let clear_without = columns(&without.values);
        assert!(
            clear_without < 0.5 * clear_with_map,
            "{clear_without} vs {clear_with_map}"
        );
    }

    #[test]
    fn the_wind_carries_the_clouds_noise_through_its_layer() {
        use smokeshadow::medium::cloud_noise::baked_density_drifted;
        let gpu = gpu();
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let seed = 5;
        let noise = CloudNoiseGenerator::new(&gpu)
            .generate(&gpu, &mut ledger, seed)
            .unwrap();
        let dims = UVec3::new(40, 12, 40);
        let params = CloudParams {
            origin_xz_m: [0.0, 0.0],
            size_xz_m: [8000.0, 8000.0],
            altitude_m: 1000.0,
            thickness_m: 1000.0,
            coverage: 0.7,
            density_per_m: 0.04,
            top_fraction: 1.0,
            shape_period_m: 3000.0,
            detail_period_m: 600.0,
            coverage_map: 1.0,
        };
        let baker = CloudBaker::new(&gpu);
        // One voxel's step along x (8000 m / 40) of wind, and a drift that is no voxel step.
        let step = Vec3::new(200.0, 0.0, 0.0);
        let still = baker
            .bake(&gpu, &mut ledger, &noise, &params, dims, Vec3::ZERO)
            .wait()
            .unwrap();
        let moved = baker
            .bake(&gpu, &mut ledger, &noise, &params, dims, step)
            .wait()
            .unwrap();
        let at = |g: &[f32], i: u32, j: u32, k: u32| g[((k * dims.y + j) * dims.x + i) as usize];
        // Carried by one voxel: voxel i + 1 now holds what voxel i held (inside the box, whose
        // edges stay), to the bake's f32 rounding of the voxel centres.
        for k in (0..dims.z).step_by(3) {
            for j in 0..dims.y {
                for i in 0..dims.x - 1 {
                    let (before, after) =
                        (at(&still.values, i, j, k), at(&moved.values, i + 1, j, k));
                    assert!(
                        (before - after).abs() < 1e-4 * params.density_per_m,
                        "({i}, {j}, {k}): {before} -> {after}"
                    );
                }
            }
        }
        // Any drift: the GPU's bake is the CPU mirror's, noise and coverage map carried, the
        // layer's box where it stands.
        let drift = Vec3::new(1234.5, 0.0, -567.25);
        let grid = baker
            .bake(&gpu, &mut ledger, &noise, &params, dims, drift)
            .wait()
            .unwrap();
        for k in (0..dims.z).step_by(5) {
            for j in (0..dims.y).step_by(3) {
                for i in (0..dims.x).step_by(5) {
                    let index = UVec3::new(i, j, k);
                    let p = bake_voxel_centre(&params, dims, index);
                    let cpu = baked_density_drifted(seed, p, &params, drift);
                    let gpu_value = at(&grid.values, i, j, k);
                    assert!(
                        (gpu_value - cpu).abs() < 1e-4 * params.density_per_m,
                        "{index}: GPU {gpu_value}, CPU {cpu}"
                    );
                }
            }
        }
        assert!(grid.values != still.values, "the cloud moved");
    }
}
