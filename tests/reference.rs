//! The reference holds on every scene and proves it: `exact`'s light (smoke transmittance times
//! the opaque occluders' visibility) against the f64 CPU closed form at the frame's shaded
//! points (core/src/render/reference_check.rs), on every embedded scene, on each scene's particles
//! read back as a bare file (framed by `particles::scene_for_file`), and on bare files of smoke
//! from 1 cm to 1 km across and 5 km from the origin, on tile lists of 16,000 and 100,000 spheres
//! and on 262,144 particles; a broken reference is refused in one line.

use smokeshadow::Wait;
mod common;

use std::path::Path;

use glam::Vec3;
use smokeshadow::particles::{self, Format};
use smokeshadow::render::reference_check::{self, TOLERANCE};
use smokeshadow::render::shaded::rms_difference;
use smokeshadow::render::{OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer};
use smokeshadow::scene::{EMBEDDED, Scene};
use smokeshadow::shadow::SplatMode;
use smokeshadow::sim::Particle;

const W: u32 = 160;
const H: u32 = 120;

/// A renderer that has rendered a frame of `scene` with `exact` (as the commands do before they
/// check).
fn render_exact(gpu: &smokeshadow::gpu::Gpu, scene: &Scene, particles: &[Particle]) -> Renderer {
    let config = common::technique("exact", 1, 512, SplatMode::Segment);
    let mut renderer = Renderer::new(gpu, W, H, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let target = OffscreenTarget::new(gpu, W, H);
    renderer
        .render(
            gpu,
            scene,
            particles,
            &RenderOptions::default(),
            &target.view,
        )
        .wait()
        .unwrap_or_else(|e| panic!("{}: {e}", scene.name));
    renderer
}

/// Renders `scene` with `exact` and runs the check.
fn check(
    gpu: &smokeshadow::gpu::Gpu,
    scene: &Scene,
    particles: &[Particle],
) -> reference_check::ReferenceCheck {
    let mut renderer = render_exact(gpu, scene, particles);
    reference_check::verify(&mut renderer, gpu, scene, particles)
        .wait()
        .unwrap_or_else(|e| panic!("{}: {e:#}", scene.name))
}

fn small(mut scene: Scene) -> Scene {
    scene.output.width_px = W;
    scene.output.height_px = H;
    scene
}

/// Writes `particles` as a bare CSV under `dir` and opens it as the CLI does.
fn bare(dir: &Path, name: &str, particles: &[Particle]) -> Scene {
    let path = dir.join(format!("{name}.csv"));
    particles::write(&path, particles, Some(Format::Csv)).unwrap();
    small(particles::open_scene(Some(&path)).unwrap())
}

/// Every embedded scene and its particles read back as a bare file: exact agrees with the f64
/// closed form within the check's tolerance at every compared point, with points on the smoke
/// and on the lit ground in each. (Before the fix of the ground's self-test, a bare file's
/// ground, whose height is not a round number, shadowed itself in bands: |ΔT| = 1 there.)
#[test]
fn exact_agrees_with_the_closed_form_on_every_embedded_scene_and_its_bare_read_back() {
    let gpu = common::gpu();
    let dir = common::scratch("reference-bare");
    for (name, _) in EMBEDDED {
        let scene = small(Scene::embedded(name).unwrap());
        let particles = particles::scene_particles(&scene).unwrap();
        let as_scene = check(&gpu, &scene, &particles);
        if scene.volume.is_some() {
            // A volume scene: its eye samples are compared, against the f64 march doubled
            // until converged (it has no particles to read back).
            assert!(
                as_scene.worst_difference <= TOLERANCE && as_scene.volume_points >= 50,
                "{name}: {as_scene}"
            );
            continue;
        }
        let file_scene = bare(&dir, name, &particles);
        let read_back = particles::scene_particles(&file_scene).unwrap();
        assert_eq!(read_back.len(), particles.len());
        let as_file = check(&gpu, &file_scene, &read_back);
        for (what, c) in [("scene", as_scene), ("bare file", as_file)] {
            assert!(c.worst_difference <= TOLERANCE, "{name} as a {what}: {c}");
            // The check compares a real sample: smoke and lit opaque points.
            assert!(
                c.points >= 100,
                "{name} as a {what}: only {} points",
                c.points
            );
        }
        let opaque = reference_check::check_points(&file_scene, &read_back, (W, H), None)
            .iter()
            .filter(|(_, k)| *k == reference_check::PointKind::Opaque)
            .count();
        assert!(
            opaque >= 50,
            "{name} as a bare file: {opaque} lit ground points"
        );
    }
}

/// A lattice of 4 x 4 x 4 overlapping spheres in a cube of side `size_m` centred on `centre`:
/// dense enough that the light ray through its far side crosses several of them.
fn lattice(size_m: f32, centre: Vec3) -> Vec<Particle> {
    let step = size_m / 4.0;
    let mut out = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            for k in 0..4 {
                let offset = Vec3::new(i as f32, j as f32, k as f32) - Vec3::splat(1.5);
                out.push(Particle {
                    position: centre + offset * step,
                    velocity: Vec3::ZERO,
                    age_s: 1.0,
                    radius_m: 0.6 * step,
                    // The same optical depth per sphere at every scale.
                    density_per_m: 2.0 / step,
                    albedo: Vec3::splat(0.8),
                });
            }
        }
    }
    out
}

/// Smoke of any size and place: the same lattice at 1 cm, 1 m and 1 km, and at 1 m 5 km from
/// the origin, each read as a bare file. `exact` stays within 1e-4 of the closed form, and a
/// converging technique at 24 channels (osm, segment splats) is as close to `exact` at the
/// shaded points as at 1 m: the framing, the light's planes and every epsilon follow the
/// smoke's size, so the scene is the same scene at every scale. (With the light's fixed 5 cm
/// near plane, the 1 cm lattice got no shadow at all from osm: T = 1 where exact gives 0.0x.)
#[test]
fn bare_files_at_every_scale_and_far_from_the_origin_are_shadowed_alike() {
    let gpu = common::gpu();
    let dir = common::scratch("reference-scales");
    let cases = [
        ("1cm", 0.01, Vec3::ZERO),
        ("1m", 1.0, Vec3::ZERO),
        ("1km", 1000.0, Vec3::ZERO),
        ("1m_at_5km", 1.0, Vec3::new(5000.0, 20.0, -3000.0)),
    ];
    let osm = common::technique("osm", 24, 512, SplatMode::Segment);
    let mut rms_at = Vec::new();
    for (name, size, centre) in cases {
        let scene = bare(&dir, name, &lattice(size, centre));
        let particles = particles::scene_particles(&scene).unwrap();
        let c = check(&gpu, &scene, &particles);
        assert!(c.worst_difference <= 1e-4, "{name}: {c}");
        // osm against exact at the frame's shaded points.
        let points: Vec<Vec3> = reference_check::check_points(&scene, &particles, (W, H), None)
            .into_iter()
            .map(|(p, _)| p)
            .collect();
        let exact = common::technique("exact", 1, 512, SplatMode::Segment);
        let t = common::probe_all(&gpu, &scene, &particles, &[exact, osm.clone()], &points);
        // The lattice shadows itself: some points are deep in it.
        let darkest = t[0].iter().copied().fold(1.0f32, f32::min);
        assert!(darkest < 0.2, "{name}: exact's darkest T {darkest}");
        let rms = rms_difference(&t[1], &t[0]);
        rms_at.push((name, rms));
    }
    let at_1m = rms_at[1].1;
    // osm's usual error at 24 channels (tests/techniques.rs holds it below 0.03 on the plume).
    assert!(at_1m < 0.03, "osm at 1 m: RMS ΔT {at_1m}");
    for &(name, rms) in &rms_at {
        assert!(
            (rms - at_1m).abs() < 0.005,
            "osm's RMS ΔT against exact is {rms} at {name} but {at_1m} at 1 m: {rms_at:?}"
        );
    }
}

/// A reference that is not exact is refused: with `none` (T = 1 everywhere) standing in for a
/// broken reference, the check fails in one line naming the worst point and both values.
#[test]
fn a_broken_reference_is_refused_in_one_line() {
    let gpu = common::gpu();
    let scene = small(Scene::thesis_plume());
    let particles = particles::scene_particles(&scene).unwrap();
    let config = common::technique("none", 1, 512, SplatMode::Segment);
    let mut renderer = Renderer::new(&gpu, W, H, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let err = reference_check::verify(&mut renderer, &gpu, &scene, &particles)
        .wait()
        .expect_err("T = 1 through the plume is not the closed form");
    let message = format!("{err:#}");
    assert!(!message.contains('\n'), "{message}");
    assert!(
        message.contains("disagrees with the f64 closed form"),
        "{message}"
    );
    assert!(message.contains("T = 1.000000 on the GPU"), "{message}");
    // And the commands refuse to go on: the same check passes for exact on the same frame.
    let c = check(&gpu, &scene, &particles);
    assert!(c.worst_difference <= TOLERANCE, "{c}");
}

/// A point drawn uniformly inside the unit ball (rejection sampling).
fn in_unit_ball(rng: &mut rand_pcg::Pcg64) -> Vec3 {
    use rand::Rng;
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length_squared() <= 1.0 {
            return v;
        }
    }
}

/// `count` spheres of 0.5 m and extinction `density_per_m` whose centres lie within 0.2 m of
/// `CLUSTER_CENTER`: every one of them covers the light tiles at the cluster's centre, so one
/// tile list holds them all.
fn cluster(count: usize, seed: u64, density_per_m: f32) -> Vec<Particle> {
    use rand::SeedableRng;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..count)
        .map(|_| Particle {
            position: CLUSTER_CENTER + in_unit_ball(&mut rng) * 0.2,
            velocity: Vec3::ZERO,
            age_s: 1.0,
            radius_m: 0.5,
            density_per_m,
            albedo: Vec3::splat(0.8),
        })
        .collect()
}

const CLUSTER_CENTER: Vec3 = Vec3::new(0.0, 1.5, 0.0);

/// The longest tile list of `renderer`'s `exact` last frame.
fn longest_tile_list(renderer: &Renderer) -> u64 {
    renderer
        .technique()
        .counters()
        .into_iter()
        .find(|(name, _)| *name == "max_tile_list")
        .unwrap()
        .1
}

/// Dense smoke is not refused: 16,000 spheres of 0.5 m whose centres lie within 0.2 m of one
/// point, so every one of them covers the tiles at the cluster's centre and one tile list holds
/// all 16,000 (beyond the 15,000 that four lookups per lighting invocation allowed on
/// llvmpipe; each invocation now lights one point). `exact` renders it and stays within 1e-4
/// of the f64 closed form at the shaded points.
#[test]
fn a_tile_list_of_sixteen_thousand_spheres_is_walked_whole() {
    let gpu = common::gpu();
    // About 1.6 of optical depth through the middle: T well inside (0, 1).
    let cluster = cluster(16_000, 16_000, 2e-4);
    let dir = common::scratch("reference-dense");
    let scene = bare(&dir, "dense", &cluster);
    let particles = particles::scene_particles(&scene).unwrap();
    let mut renderer = render_exact(&gpu, &scene, &particles);
    let longest = longest_tile_list(&renderer);
    assert!(longest >= 15_001, "longest tile list {longest}");
    let c = reference_check::verify(&mut renderer, &gpu, &scene, &particles)
        .wait()
        .unwrap();
    assert!(c.points >= 100, "only {} points", c.points);
    assert!(c.worst_difference <= 1e-4, "{c}");
}

/// A list beyond llvmpipe's loop budget is walked whole: 100,000 spheres of 0.5 m whose centres
/// lie within 0.2 m of one point all cover the tiles at the cluster's centre, so one list holds
/// 100,000 entries, beyond the 65,535 loop iterations one invocation may take (the walk takes
/// eight entries an iteration). `exact`'s T along the light ray through the cluster (before it,
/// inside it, beyond it, and off its axis) stays within 1e-4 of the f64 closed form.
#[test]
fn a_tile_list_beyond_the_loop_budget_is_walked_whole() {
    let gpu = common::gpu();
    let center = CLUSTER_CENTER;
    // About 1.6 of optical depth through the middle, as the 16,000 spheres above.
    let cluster = cluster(100_000, 100_000, 2e-4 * 0.16);
    let dir = common::scratch("reference-beyond-budget");
    let scene = bare(&dir, "beyond", &cluster);
    let particles = particles::scene_particles(&scene).unwrap();
    let config = common::technique("exact", 1, 512, SplatMode::Segment);
    let mut renderer = Renderer::new(&gpu, W, H, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let light = scene.light.position;
    let side = (center - light).cross(Vec3::Y).normalize_or(Vec3::X);
    let points: Vec<Vec3> = (0..=40)
        .flat_map(|i| {
            let along = light + (center - light) * (0.6 + 0.02 * i as f32);
            [
                along,
                along + side * 0.05,
                along - Vec3::Y.cross(side) * 0.1,
            ]
        })
        .collect();
    let gpu_t = renderer
        .probe(&gpu, &scene, &particles, &points)
        .wait()
        .unwrap();
    let longest = longest_tile_list(&renderer);
    assert!(longest > 65_535, "longest tile list {longest}");
    let mut darkest = 1.0f32;
    for (p, t) in points.iter().zip(&gpu_t) {
        let cpu = smokeshadow::shadow::closed_form::transmittance(light, *p, &particles);
        darkest = darkest.min(cpu);
        assert!(
            (t - cpu).abs() <= 1e-4,
            "at {p}: exact {t}, closed form {cpu}"
        );
    }
    // The ray crosses the cluster: the points beyond it are in its shadow.
    assert!(darkest < 0.5, "darkest T {darkest}");
}

/// At scale: the thesis plume grown to 262,144 particles (each of its 2,500 replaced by about
/// 105 within its sphere, radii times (2,500/262,144)^(1/3) and τ kept, as `--particles` scales
/// a scene, so that the smoke keeps its optical depth and its lists grow long), rendered with
/// `exact` and checked at the frame's shaded points on the smoke and the ground: within 1e-4 of
/// the f64 closed form at every one.
#[test]
fn exact_agrees_with_the_closed_form_at_262144_particles() {
    use rand::SeedableRng;
    const COUNT: usize = 262_144;
    let gpu = common::gpu();
    let scene = small(Scene::thesis_plume());
    let plume = particles::scene_particles(&scene).unwrap();
    let scale = (plume.len() as f32 / COUNT as f32).cbrt();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(262_144);
    let grown: Vec<Particle> = (0..COUNT)
        .map(|i| {
            let source = &plume[i % plume.len()];
            Particle {
                position: source.position + in_unit_ball(&mut rng) * source.radius_m,
                radius_m: source.radius_m * scale,
                ..*source
            }
        })
        .collect();
    let mut renderer = render_exact(&gpu, &scene, &grown);
    let c = reference_check::verify(&mut renderer, &gpu, &scene, &grown)
        .wait()
        .unwrap();
    assert!(c.points >= 100, "only {} points", c.points);
    assert!(c.worst_difference <= 1e-4, "{c}");
}
