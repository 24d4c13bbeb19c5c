//! The cloud noise on the CPU (src/medium/cloud_noise.rs; its WGSL is validated and its structs'
//! layouts checked by tests/shaders.rs, its GPU generators held to it by tests/medium.rs): it
//! tiles, is deterministic, stays in 0..1 and varies; the density obeys the shape the 2018
//! thesis gives it (`004_...txt` §3.1): no cloud without coverage, more with
//! more coverage, none at the layer's base and top, and detail erosion only ever removes.

use glam::{Vec3, Vec4};
use smokeshadow::medium::cloud_noise::{
    CloudParams, DETAIL_SIZE, FLOATS_PER_TEXEL, SHAPE_SIZE, cloud_base_density, cloud_density,
    cloud_density_height, cloud_layer_point, cloud_shape_noise, detail_texels, detail_voxel, remap,
    shape_voxel,
};

/// A small deterministic generator for sample positions (the tests' own, not the noise's hash).
struct Lcg(u64);

impl Lcg {
    fn below(&mut self, n: u32) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 33) as u32) % n
    }

    fn unit(&mut self) -> f32 {
        self.below(1 << 24) as f32 / (1u32 << 24) as f32
    }
}

/// Shape and detail samples at random texels of both textures for `seed`.
fn samples(seed: u32, count: usize) -> Vec<([f32; 4], [f32; 3])> {
    let mut rng = Lcg(u64::from(seed) + 99);
    (0..count)
        .map(|_| {
            let s = [0; 3].map(|_| rng.below(SHAPE_SIZE));
            let d = [0; 3].map(|_| rng.below(DETAIL_SIZE));
            (
                shape_voxel(seed, s[0], s[1], s[2]),
                detail_voxel(seed, d[0], d[1], d[2]),
            )
        })
        .collect()
}

/// Every noise repeats exactly once per texture on every axis. The functions take unwrapped
/// texel coordinates and never reduce them modulo the size themselves: only the lattice's cells
/// are wrapped. So equality at x and x + size shows the lattice itself is periodic, hence the
/// texture seamless (the pair (size − 1, size) is an ordinary pair of neighbours). Exact
/// equality: the lattice positions are exact integers and fractions k / size, so both sides run
/// the same float operations on the same inputs.
#[test]
fn noise_tiles_exactly_with_the_texture_period_on_every_axis() {
    let mut rng = Lcg(3);
    for seed in [0, 1, 0xdead_beef] {
        for i in 0..64 {
            // The corners of the texture first, then random texels.
            let corner = |n: u32, bit: u32| if i & bit != 0 { n - 1 } else { 0 };
            let pick =
                |rng: &mut Lcg, n: u32, bit| if i < 8 { corner(n, bit) } else { rng.below(n) };
            let (n, m) = (SHAPE_SIZE, DETAIL_SIZE);
            let (x, y, z) = (
                pick(&mut rng, n, 1),
                pick(&mut rng, n, 2),
                pick(&mut rng, n, 4),
            );
            let base = shape_voxel(seed, x, y, z);
            for (dx, dy, dz) in [(n, 0, 0), (0, n, 0), (0, 0, n), (n, 2 * n, 3 * n)] {
                assert_eq!(
                    shape_voxel(seed, x + dx, y + dy, z + dz),
                    base,
                    "shape seed {seed} at ({x}, {y}, {z}) + ({dx}, {dy}, {dz})"
                );
            }
            let (x, y, z) = (
                pick(&mut rng, m, 1),
                pick(&mut rng, m, 2),
                pick(&mut rng, m, 4),
            );
            let base = detail_voxel(seed, x, y, z);
            for (dx, dy, dz) in [(m, 0, 0), (0, m, 0), (0, 0, m), (m, 2 * m, 3 * m)] {
                assert_eq!(
                    detail_voxel(seed, x + dx, y + dy, z + dz),
                    base,
                    "detail seed {seed} at ({x}, {y}, {z}) + ({dx}, {dy}, {dz})"
                );
            }
        }
    }
}

/// The same seed gives the same bits; another seed gives another texture, not a shifted or
/// mostly equal one: nearly every texel differs, by 0.1 on average (the channels' spread is
/// ~0.1, so two independent textures differ by about that much).
#[test]
fn noise_is_deterministic_and_changes_with_the_seed() {
    assert_eq!(samples(5, 200), samples(5, 200));
    let a = samples(5, 400);
    let mut b_rng = Lcg(5 + 99);
    let mut differing = 0;
    let mut total = 0;
    let mut abs_sum = 0.0;
    for (shape_a, detail_a) in &a {
        // The same texels as `samples(5, ..)` picked, seed 6's values there.
        let s = [0; 3].map(|_| b_rng.below(SHAPE_SIZE));
        let d = [0; 3].map(|_| b_rng.below(DETAIL_SIZE));
        let shape_b = shape_voxel(6, s[0], s[1], s[2]);
        let detail_b = detail_voxel(6, d[0], d[1], d[2]);
        for (va, vb) in shape_a
            .iter()
            .chain(detail_a)
            .zip(shape_b.iter().chain(&detail_b))
        {
            total += 1;
            differing += usize::from(va != vb);
            abs_sum += (va - vb).abs();
        }
    }
    assert!(
        differing as f32 > 0.99 * total as f32,
        "{differing} of {total} differ"
    );
    let mean_abs = abs_sum / total as f32;
    assert!(
        mean_abs > 0.05,
        "seeds 5 and 6 differ by {mean_abs} on average"
    );

    // The whole-buffer mirror is the per-texel function in the generators' layout.
    let texels = detail_texels(5);
    assert_eq!(
        texels.len(),
        (DETAIL_SIZE.pow(3) * FLOATS_PER_TEXEL) as usize
    );
    let (x, y, z) = (3, 17, 30);
    let at = (((z * DETAIL_SIZE + y) * DETAIL_SIZE + x) * FLOATS_PER_TEXEL) as usize;
    let [r, g, b] = detail_voxel(5, x, y, z);
    assert_eq!(texels[at..at + 4], [r, g, b, 0.0]);
}

/// Every channel is in 0..1 (the textures are stored unclamped, so this must hold by
/// construction: Worley 1 − min(F1, 1), convex FBM weights, a clamped Perlin FBM and a remap of
/// it into [worley, 1]); and each has a spread a cloud can be carved from: a standard deviation
/// over 0.05 (measured over these samples: 0.073..0.139) and a range over half of 0..1 for the
/// Worley FBMs (measured 0.61..0.80). The Perlin–Worley channel's floor is its Worley FBM
/// (GPU Pro 7's dilation maps Perlin into [worley, 1]), so it spans less: over 0.3 (measured
/// 0.45..0.49, from about 0.46 to 0.95).
#[test]
fn noise_stays_in_unit_interval_and_varies() {
    for seed in [0, 1, 42] {
        let s = samples(seed, 1500);
        for channel in 0..7 {
            let values: Vec<f32> = s
                .iter()
                .map(|(shape, detail)| {
                    if channel < 4 {
                        shape[channel]
                    } else {
                        detail[channel - 4]
                    }
                })
                .collect();
            let (min, max) = values
                .iter()
                .fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
            assert!(
                (0.0..=1.0).contains(&min) && (0.0..=1.0).contains(&max),
                "seed {seed} channel {channel}: {min}..{max}"
            );
            let n = values.len() as f32;
            let mean = values.iter().sum::<f32>() / n;
            let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / n).sqrt();
            assert!(sd > 0.05, "seed {seed} channel {channel}: sd {sd}");
            let min_range = if channel == 0 { 0.3 } else { 0.5 };
            assert!(
                max - min > min_range,
                "seed {seed} channel {channel}: {min}..{max}"
            );
        }
    }
}

fn layer() -> CloudParams {
    // The 2018 thesis' layer (004 §3.1.1: base 400 m, tops up to 1000 m), 10 km square.
    CloudParams {
        origin_xz_m: [-5000.0, -5000.0],
        size_xz_m: [10000.0, 10000.0],
        altitude_m: 400.0,
        thickness_m: 600.0,
        coverage: 0.6,
        density_per_m: 0.02,
        top_fraction: 1.0,
        shape_period_m: 4000.0,
        detail_period_m: 600.0,
        coverage_map: 0.0,
    }
}

/// Density inputs: real noise samples at random layer points with heights spread over 0..1.
fn density_samples(count: usize) -> Vec<(Vec3, Vec4, Vec3)> {
    let mut rng = Lcg(17);
    samples(11, count)
        .into_iter()
        .map(|(shape, detail)| {
            let p = Vec3::new(rng.unit(), rng.unit(), rng.unit());
            (p, Vec4::from_array(shape), Vec3::from_array(detail))
        })
        .collect()
}

#[test]
fn no_coverage_no_cloud() {
    let mut params = layer();
    for (p, shape, detail) in density_samples(500) {
        params.coverage = 0.8;
        assert_eq!(cloud_density(p, shape, detail, 0.0, &params), 0.0);
        assert_eq!(cloud_base_density(p, shape, 0.0, &params), 0.0);
        params.coverage = 0.0;
        assert_eq!(cloud_density(p, shape, detail, 1.0, &params), 0.0);
    }
}

/// More coverage, more cloud: for every sample the density does not fall as the global coverage
/// rises 0.1..1.0 (the threshold 1 − g_c falls and the erosion 0.35 e^(−0.75 g_c) shrinks, both
/// monotone, 004 eq. 12 and 14), and the mean rises strictly. The pointwise slack, 1e-6 of the
/// density scale, is f32 rounding in the remaps (a few ulps of values <= 1), far below a step's
/// change; the same holds for the coverage map's value at fixed global coverage.
#[test]
fn density_grows_with_coverage() {
    let s = density_samples(1500);
    let mut params = layer();
    let slack = 1e-6 * params.density_per_m;
    let mut means = Vec::new();
    let mut previous: Option<Vec<f32>> = None;
    for step in 1..=10 {
        params.coverage = step as f32 / 10.0;
        let d: Vec<f32> = s
            .iter()
            .map(|&(p, shape, detail)| cloud_density(p, shape, detail, 1.0, &params))
            .collect();
        if let Some(prev) = &previous {
            for (i, (now, before)) in d.iter().zip(prev).enumerate() {
                assert!(
                    now + slack >= *before,
                    "sample {i}, g_c {}: {before} -> {now}",
                    params.coverage
                );
            }
        }
        means.push(d.iter().sum::<f32>() / d.len() as f32);
        previous = Some(d);
    }
    assert!(
        means.windows(2).all(|w| w[1] > w[0]),
        "mean density over g_c 0.1..1.0: {means:?}"
    );

    params.coverage = 0.7;
    for &(p, shape, detail) in &s {
        let mut before = 0.0;
        for step in 0..=10 {
            let d = cloud_density(p, shape, detail, step as f32 / 10.0, &params);
            assert!(
                d + slack >= before,
                "map coverage {}: {before} -> {d}",
                step as f32 / 10.0
            );
            before = d;
        }
    }
}

/// The height gradients close the layer: density 0 at the base and top, and going to 0 there as
/// fast as 004's gradients say: near the base DA <= p_h (eq. 8: p_h times at most 1), near the
/// top DA <= (1 − p_h) / 0.1 (eq. 9); and 0 above the cloud tops (eq. 6) when they sit lower.
#[test]
fn density_vanishes_at_the_base_and_top_of_the_layer() {
    let mut params = layer();
    params.coverage = 1.0;
    let scale = params.density_per_m;
    for (p, shape, detail) in density_samples(400) {
        let at = |h: f32, params: &CloudParams| {
            cloud_density(Vec3::new(p.x, h, p.z), shape, detail, 1.0, params)
        };
        assert_eq!(at(0.0, &params), 0.0);
        assert_eq!(at(1.0, &params), 0.0);
        for eps in [1e-4, 1e-3, 1e-2] {
            assert!(
                at(eps, &params) <= scale * eps,
                "base + {eps}: {}",
                at(eps, &params)
            );
            let top = at(1.0 - eps, &params);
            // eps / 0.1 plus a few ulps of 1 − eps lost in the subtraction.
            assert!(top <= scale * (eps / 0.1 + 1e-6), "top − {eps}: {top}");
        }
        // Outside the layer box, on any axis.
        for q in [
            Vec3::new(p.x, -0.01, p.z),
            Vec3::new(p.x, 1.01, p.z),
            Vec3::new(-0.01, p.y, p.z),
            Vec3::new(p.x, p.y, 1.01),
        ] {
            assert_eq!(cloud_density(q, shape, detail, 1.0, &params), 0.0);
        }
        let mut low = params;
        low.top_fraction = 0.6;
        for h in [0.6, 0.7, 0.95] {
            assert_eq!(at(h, &low), 0.0, "above the tops at {h}");
        }
    }
    assert_eq!(cloud_density_height(0.0), 0.0);
    assert_eq!(cloud_density_height(1.0), 0.0);
}

/// Detail erosion only removes: SAT((b − m) / (1 − m)) <= b for b in 0..1 and m in 0..0.35
/// (004 eq. 16; equality at b = 1), so the final cloud lies inside its base shape, which is what
/// lets a march take long steps on the base shape alone (004 §3.2). The slack, 4 ulps relative,
/// is the remap's f32 rounding. Erosion must also actually remove something on average.
/// Both are in 0..density_per_m.
#[test]
fn erosion_only_removes_density() {
    let mut params = layer();
    let (mut eroded_sum, mut base_sum) = (0.0, 0.0);
    for coverage in [0.3, 0.6, 1.0] {
        params.coverage = coverage;
        for (p, shape, detail) in density_samples(1000) {
            let eroded = cloud_density(p, shape, detail, 1.0, &params);
            let base = cloud_base_density(p, shape, 1.0, &params);
            assert!(
                eroded <= base * (1.0 + 4.0 * f32::EPSILON),
                "g_c {coverage} at {p}: eroded {eroded} > base {base}"
            );
            assert!((0.0..=params.density_per_m).contains(&eroded));
            assert!((0.0..=params.density_per_m).contains(&base));
            eroded_sum += eroded;
            base_sum += base;
        }
    }
    assert!(
        eroded_sum < 0.97 * base_sum,
        "erosion removed too little: {eroded_sum} of {base_sum}"
    );
}

/// The thesis' formulas, written out here independently of the module: eq. 11 for a chosen
/// shape sample, and eq. 1's remap.
#[test]
fn shape_noise_and_remap_follow_the_thesis() {
    assert_eq!(remap(0.66, 0.0, 1.0, 0.0, 2.0), 1.32); // 004 B.1's example
    let shape = Vec4::new(0.7, 0.4, 0.5, 0.6);
    let fbm = 0.4 * 0.625 + 0.5 * 0.25 + 0.6 * 0.125;
    let expected = (0.7 - (fbm - 1.0)) / (1.0 - (fbm - 1.0));
    assert!((cloud_shape_noise(shape) - expected).abs() < 1e-6);
    // Pure Perlin–Worley 1 with any FBM is 1; 0 with FBM 1 is 0 (the remap's ends).
    assert_eq!(cloud_shape_noise(Vec4::new(1.0, 0.3, 0.3, 0.3)), 1.0);
    assert_eq!(cloud_shape_noise(Vec4::new(0.0, 1.0, 1.0, 1.0)), 0.0);
}

#[test]
fn layer_point_maps_the_box_to_the_unit_cube_and_params_validate() {
    let params = layer();
    assert_eq!(params.validate(), Ok(()));
    let lo = cloud_layer_point(Vec3::new(-5000.0, 400.0, -5000.0), &params);
    let hi = cloud_layer_point(Vec3::new(5000.0, 1000.0, 5000.0), &params);
    assert_eq!((lo, hi), (Vec3::ZERO, Vec3::ONE));

    let bad = [
        (
            "thickness_m",
            CloudParams {
                thickness_m: 0.0,
                ..params
            },
        ),
        (
            "coverage",
            CloudParams {
                coverage: 1.5,
                ..params
            },
        ),
        (
            "density_per_m",
            CloudParams {
                density_per_m: -1.0,
                ..params
            },
        ),
        (
            "top_fraction",
            CloudParams {
                top_fraction: 0.0,
                ..params
            },
        ),
        (
            "shape_period_m",
            CloudParams {
                shape_period_m: f32::NAN,
                ..params
            },
        ),
        (
            "altitude_m",
            CloudParams {
                altitude_m: f32::INFINITY,
                ..params
            },
        ),
    ];
    for (field, p) in bad {
        let err = p.validate().expect_err(field);
        assert_eq!(err.field, field);
        assert!(err.to_string().contains(field), "{err}");
    }
}

#[test]
fn the_coverage_map_tiles_and_holds_both_clear_sky_and_cloud() {
    use smokeshadow::medium::cloud_noise::{COVERAGE_SIZE, coverage_texel};
    let n = COVERAGE_SIZE;
    let mut values = Vec::new();
    for z in (0..n).step_by(8) {
        for x in (0..n).step_by(8) {
            let v = coverage_texel(3, x, z);
            // Periodic over the layer: the texel one period on is the same value, exactly (the
            // lattice is integer arithmetic).
            assert_eq!(v, coverage_texel(3, x + n, z));
            assert_eq!(v, coverage_texel(3, x, z + n));
            assert!((0.0..=1.0).contains(&v), "{v}");
            values.push(v);
        }
    }
    // Fields of each: at least a tenth of the map fully clear and a tenth fully cloudy.
    let clear = values.iter().filter(|v| **v == 0.0).count() as f64 / values.len() as f64;
    let cloudy = values.iter().filter(|v| **v == 1.0).count() as f64 / values.len() as f64;
    assert!(
        clear > 0.1 && cloudy > 0.1,
        "clear {clear}, cloudy {cloudy}"
    );
    assert_ne!(coverage_texel(3, 17, 40), coverage_texel(4, 17, 40));
}
