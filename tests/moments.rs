//! GPU tests of the moment-based maps (`msm`, `tmsm`; issue 12): the lookup against its CPU
//! mirror (`shadow::moment_math`) on the analytic sphere, the bounds against the closed form
//! through overlapping spheres, convergence as the moments grow, what the bias and the
//! overestimation do, and finite T on degenerate texels. They run on lavapipe and fail, never
//! skip, without an adapter.

mod common;

use common::{PlumeAgainstExact, ReversedOrder, gpu, probe_all, sphere, technique};
use glam::Vec3;
use smokeshadow::render::TechniqueConfig;
use smokeshadow::render::shaded::rms_difference;
use smokeshadow::scene::Scene;
use smokeshadow::shadow::moment_math::{Basis, Moments, Reconstruction};
use smokeshadow::shadow::{LightSpace, SplatMode, closed_form, find_param};
use smokeshadow::sim::Particle;

/// The two families, by registry name.
const FAMILIES: [&str; 2] = ["msm", "tmsm"];
/// Budgets buying 2, 3 and 4 roots in either family (5, 7 and 9 channels).
const ROOT_BUDGETS: [u32; 3] = [5, 7, 9];

/// `name` at `channels` with segment splats and the parameters `values` set.
fn config(name: &str, channels: u32, res: u32, values: &[(&str, f32)]) -> TechniqueConfig {
    let mut c = technique(name, channels, res, SplatMode::Segment);
    for (key, value) in values {
        smokeshadow::shadow::set_param(&mut c.params, &format!("{name}_{key}"), &(*value).into())
            .unwrap();
    }
    c
}

/// The default of `name`'s parameter `key`.
fn default_of(name: &str, key: &str) -> f64 {
    f64::from(
        find_param(&format!("{name}_{key}"))
            .unwrap()
            .default
            .unwrap(),
    )
}

fn basis(name: &str) -> Basis {
    match name {
        "msm" => Basis::Power,
        _ => Basis::Trigonometric {
            wrapping_zone_rad: default_of(name, "wrapping_zone_rad"),
        },
    }
}

/// Roots at `channels` (5, 7, 9 -> 2, 3, 4) in either family.
fn roots(channels: u32) -> usize {
    (channels as usize - 1) / 2
}

fn all_in_unit_range(t: &[f32]) -> bool {
    t.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v))
}

fn mean(t: &[f32]) -> f64 {
    t.iter().map(|&v| f64::from(v)).sum::<f64>() / t.len() as f64
}

#[test]
fn the_gpu_lookup_matches_its_cpu_mirror_on_the_analytic_sphere() {
    let gpu = gpu();
    let scene = sphere::scene();
    let particle = sphere::particle();
    let light = LightSpace::cone(&scene.light, &[particle]);
    let depth01 = |dist: f32| f64::from((dist - light.near_m) / (light.far_m - light.near_m));
    let (points, _) = sphere::samples();
    // Each probed ray's texel holds one chord: τ(1 − d/r)·2w spread over [t_c − w, t_c + w].
    let samples_per_ray = points.len() / sphere::IMPACT.len();
    for name in FAMILIES {
        for channels in ROOT_BUDGETS {
            let gpu_t = probe_all(
                &gpu,
                &scene,
                &[particle],
                &[config(name, channels, 512, &[])],
                &points,
            )
            .remove(0);
            let reconstruction = Reconstruction {
                basis: basis(name),
                roots: roots(channels),
                bias: default_of(name, "bias"),
                overestimation: default_of(name, "overestimation"),
            };
            let mut worst = 0.0f64;
            for (ray, d) in sphere::IMPACT.iter().enumerate() {
                let sin = d / sphere::LIGHT_HEIGHT;
                let t_c = sphere::LIGHT_HEIGHT * (1.0 - sin * sin).sqrt();
                let w = (sphere::RADIUS * sphere::RADIUS - d * d).sqrt();
                let od = sphere::TAU * (1.0 - d / sphere::RADIUS) * 2.0 * w;
                let mut m = Moments::empty(reconstruction.basis, reconstruction.roots);
                m.add(
                    reconstruction.basis,
                    f64::from(od),
                    depth01(t_c - w),
                    depth01(t_c + w),
                );
                for i in 0..samples_per_ray {
                    let k = ray * samples_per_ray + i;
                    let dist = points[k].distance(light.position);
                    let cpu = reconstruction.transmittance(&m, depth01(dist));
                    if std::env::var("DEBUG_MOMENTS").is_ok() {
                        println!(
                            "{name} {channels} ray {ray} d01 {:.4} cpu {cpu:.5} gpu {:.5}",
                            depth01(dist),
                            gpu_t[k]
                        );
                    }
                    worst = worst.max((cpu - f64::from(gpu_t[k])).abs());
                }
            }
            println!("{name} at {channels} channels: GPU against CPU mirror, worst {worst:.2e}");
            // The GPU blends the moments of the four texels around each point, whose rays cut
            // chords up to 1.1 cm longer or shorter than the probed ray's (a 512² map over a
            // 10° cone, at the sphere's edge), and it works in f32. Measured: ≤ 3.5e-3.
            assert!(
                worst < 8e-3,
                "{name} at {channels} channels: GPU T differs from the CPU mirror by {worst}"
            );
        }
    }
}

/// Three overlapping spheres lit obliquely (as the `exact` test in techniques.rs), and points
/// along five light rays through them with the closed-form T.
fn overlapping_spheres() -> (Scene, Vec<Particle>, Vec<Vec3>, Vec<f32>) {
    let mut scene = sphere::scene();
    scene.light.position = Vec3::new(-6.0, 8.0, 3.0);
    scene.light.cone_angle_deg = 25.0;
    let particles: Vec<Particle> = [
        (Vec3::new(0.0, 0.0, 0.0), 1.0f32, 1.5f32),
        (Vec3::new(0.6, 0.3, -0.2), 0.8, 2.0),
        (Vec3::new(-0.5, 0.5, 0.4), 0.6, 3.0),
    ]
    .iter()
    .map(|&(position, radius_m, density_per_m)| Particle {
        position,
        radius_m,
        density_per_m,
        ..sphere::particle()
    })
    .collect();
    let light = scene.light.position;
    let mut points = Vec::new();
    for aim in [
        Vec3::ZERO,
        Vec3::new(0.5, 0.2, 0.0),
        Vec3::new(-0.4, 0.6, 0.3),
        Vec3::new(0.0, -0.7, 0.5),
    ] {
        let dir = (aim - light).normalize();
        let centre_t = (aim - light).length();
        points.extend((0..=30).map(|i| light + dir * (centre_t - 2.0 + 4.0 * i as f32 / 30.0)));
    }
    let expected = points
        .iter()
        .map(|&p| closed_form::transmittance(light, p, &particles))
        .collect();
    (scene, particles, points, expected)
}

#[test]
fn the_bounds_bracket_the_closed_form_and_tighten_as_the_moments_grow() {
    // η = 0 bounds the optical depth in front of a point from below (T from above), η = 1 from
    // above (T from below), for any distribution with the texel's moments: the truth lies
    // between. More moments, fewer such distributions: a narrower bracket.
    let gpu = gpu();
    let (scene, particles, points, expected) = overlapping_spheres();
    for name in FAMILIES {
        let mut widths = Vec::new();
        for channels in ROOT_BUDGETS {
            let t = probe_all(
                &gpu,
                &scene,
                &particles,
                &[
                    config(
                        name,
                        channels,
                        512,
                        &[("overestimation", 0.0), ("bias", 5e-5)],
                    ),
                    config(
                        name,
                        channels,
                        512,
                        &[("overestimation", 1.0), ("bias", 5e-5)],
                    ),
                ],
                &points,
            );
            let (upper, lower) = (&t[0], &t[1]);
            assert!(
                all_in_unit_range(upper) && all_in_unit_range(lower),
                "{name}"
            );
            let mut outside = 0.0f32;
            for ((u, l), e) in upper.iter().zip(lower).zip(&expected) {
                outside = outside.max(l - e).max(e - u);
            }
            // The slack: the bracket is that of the four rays blended around a point, and of
            // the moments pulled towards uniform by β = 5e-5 (measured: ≤ 2e-4).
            println!(
                "{name} at {channels} channels: mean bracket {:.4}, farthest outside {outside:.2e}",
                mean(upper) - mean(lower)
            );
            assert!(
                outside < 0.015,
                "{name} at {channels} channels: the closed form lies {outside} outside the bounds"
            );
            widths.push(mean(upper) - mean(lower));
        }
        assert!(
            widths.windows(2).all(|w| w[1] < w[0]),
            "{name}: the bracket must narrow with more moments: {widths:?}"
        );
    }
}

#[test]
fn error_against_exact_on_the_plume_falls_as_the_moments_grow() {
    let gpu = gpu();
    let plume = PlumeAgainstExact::new(&gpu, 4);
    let res = plume.res();
    for name in FAMILIES {
        let configs: Vec<_> = ROOT_BUDGETS
            .iter()
            .map(|&b| config(name, b, res, &[]))
            .collect();
        let errors = plume.errors(&gpu, &configs);
        println!("{name}: RMS T error against exact at 5/7/9 channels: {errors:?}");
        assert!(
            errors[2] < errors[0],
            "{name}: 4 roots must beat 2 on the plume: {errors:?}"
        );
    }
}

#[test]
fn overestimation_darkens_and_bias_costs_accuracy_on_the_analytic_sphere() {
    let gpu = gpu();
    let scene = sphere::scene();
    let particles = [sphere::particle()];
    let (points, analytic) = sphere::samples();
    for name in FAMILIES {
        let study = |key: &str, values: &[f32]| -> Vec<Vec<f32>> {
            let configs: Vec<_> = values
                .iter()
                .map(|&v| config(name, 9, 512, &[(key, v)]))
                .collect();
            let results = probe_all(&gpu, &scene, &particles, &configs, &points);
            for (t, v) in results.iter().zip(values) {
                assert!(all_in_unit_range(t), "{name} {key} = {v}");
                println!(
                    "{name} {key} = {v}: mean T {:.4}, RMS against analytic {:.4}",
                    mean(t),
                    rms_difference(t, &analytic)
                );
            }
            results
        };
        // η weights the receiver's own node: the share in front is lower + η·w0, so T falls
        // with η at every point (up to f32 rounding), and on average strictly.
        let by_eta = study("overestimation", &[0.0, 0.4, 1.0]);
        for pair in by_eta.windows(2) {
            for (i, (low, high)) in pair[0].iter().zip(&pair[1]).enumerate() {
                assert!(
                    *high <= low + 1e-5,
                    "{name}: T rose with η at sample {i}: {low} -> {high}"
                );
            }
            assert!(mean(&pair[1]) < mean(&pair[0]), "{name}: η must darken");
        }
        // β mixes a uniform distribution into the texel's: the moments describe a blurrier
        // ray than the one the sphere casts, and the error against the analytic curve grows.
        let errors: Vec<f64> = study("bias", &[5e-5, 1e-2, 1e-1])
            .iter()
            .map(|t| rms_difference(t, &analytic))
            .collect();
        assert!(
            errors.windows(2).all(|w| w[1] > w[0]),
            "{name}: more bias must cost accuracy: {errors:?}"
        );
    }
}

#[test]
fn degenerate_texels_give_finite_transmittance() {
    let gpu = gpu();
    let scene = sphere::scene();
    let axis: Vec<Vec3> = (0..=60)
        .map(|i| Vec3::new(0.0, 9.0 - 12.0 * i as f32 / 60.0, 0.0))
        .collect();
    let p = sphere::particle();
    // (what, particles, whether the 512² map resolves them: a 1 cm particle spans three texels
    // of the map, which blends its optical depth with its neighbours' behind it, as every map
    // at this resolution does, so T behind it is checked against the closed form only where
    // the particles are resolved).
    let cases: [(&str, Vec<Particle>, bool); 3] = [
        // Almost nothing: b0 just above the empty threshold, moments all rounding.
        (
            "a faint particle",
            vec![Particle {
                density_per_m: 1e-5,
                ..p
            }],
            true,
        ),
        (
            "a thin particle",
            vec![Particle {
                radius_m: 0.01,
                density_per_m: 50.0,
                ..p
            }],
            false,
        ),
        (
            "two far-apart particles",
            vec![
                Particle {
                    position: Vec3::new(0.0, 7.0, 0.0),
                    radius_m: 0.3,
                    density_per_m: 3.0,
                    ..p
                },
                Particle {
                    position: Vec3::new(0.0, -2.0, 0.0),
                    radius_m: 0.3,
                    density_per_m: 3.0,
                    ..p
                },
            ],
            true,
        ),
    ];
    for (what, particles, resolved) in &cases {
        let light = scene.light.position;
        let expected: Vec<f32> = axis
            .iter()
            .map(|&q| closed_form::transmittance(light, q, particles))
            .collect();
        for name in FAMILIES {
            let configs: Vec<_> = ROOT_BUDGETS
                .iter()
                .map(|&b| config(name, b, 512, &[]))
                .collect();
            for (b, t) in probe_all(&gpu, &scene, particles, &configs, &axis)
                .iter()
                .enumerate()
            {
                assert!(all_in_unit_range(t), "{name}, {what}: {t:?}");
                // In front of all the smoke (the axis starts 1.7 m before the first particle),
                // nothing may be in front of the point.
                assert!(
                    t[0] > 0.999,
                    "{name}, {what}: T = {} before the smoke",
                    t[0]
                );
                // The power moments' bound is non-decreasing in depth (the least mass in front
                // of z, over all distributions with the moments, grows with z), so T never
                // rises along a light ray, up to f32 rounding. The trigonometric one is no such
                // bound: a root in the wrapping zone counts by a ramp, and T may rise in the
                // gap between two puffs (measured: by up to 0.03 between the far-apart pair at
                // the default β; 0.19 at β = 5e-3).
                let rise = if name == "msm" { 1e-3 } else { 0.05 };
                for w in t.windows(2) {
                    assert!(
                        w[1] <= w[0] + rise,
                        "{name}, {what}, budget {}: T rises along the ray: {t:?}",
                        ROOT_BUDGETS[b]
                    );
                }
                // Behind all of it, every bound holds the whole optical depth.
                let last = *t.last().unwrap();
                let want = *expected.last().unwrap();
                assert!(
                    !resolved || (last - want).abs() < 0.02,
                    "{name}, {what}: T = {last} behind the smoke, closed form {want}"
                );
            }
        }
    }
}

#[test]
fn power_moments_amplify_the_rounding_of_the_draw_order_only_at_a_few_texels() {
    // The maps are sums, so the draw order changes only their f32 rounding; 8 power moments'
    // ill-conditioned Hankel matrix amplifies it at a few texels (the registry does not call
    // msm order independent for that). Reversing the order, as the shared test does: most
    // points keep T within the shared 5e-3, and the RMS change stays small.
    let gpu = gpu();
    let orders = ReversedOrder::new();
    let points = &orders.points;
    for splat in [SplatMode::Point, SplatMode::Segment] {
        let config = technique("msm", 16, orders.resolution_px(), splat);
        let (front, back) = orders.probe(&gpu, &config);
        let moved = front
            .iter()
            .zip(&back)
            .filter(|(a, b)| (*a - *b).abs() > 5e-3)
            .count();
        let rms = rms_difference(&front, &back);
        println!(
            "msm {splat:?}: {moved} of {} points moved by more than 5e-3, RMS {rms:.2e}",
            points.len()
        );
        // Measured at the tuned β = 1.57e-6 (docs/tuned_params.toml): 35 points of 10,249 (point
        // splats), RMS 0.017, 7 with segment splats, RMS 4.1e-3, a few points moving far (at
        // β = 2.6e-6, 17 points, RMS 0.022; at the former β = 5e-3, 1 point, RMS 5.3e-3). A map that depended on the order (an overwrite instead of a sum) would move
        // most of them. `tune` keeps every candidate within 0.01 RMS on its training scenes.
        assert!(
            moved * 100 < points.len(),
            "msm {splat:?}: {moved} of {} points moved",
            points.len()
        );
        assert!(rms < 0.03, "msm {splat:?}: RMS change {rms}");
    }
}
