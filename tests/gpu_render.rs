//! GPU tests of the frame on the thesis scene (reduced size) and of spherical billboards.
//! They run on lavapipe in CI and fail, never skip, without an adapter.

use smokeshadow::Wait;
mod common;

use common::{
    REDUCED_H as H, REDUCED_W as W, gpu, luminance, reduced_plume, segment_hits_box, technique,
};
use glam::Vec3;
use smokeshadow::render::{CameraMatrices, OffscreenFrame, RenderOptions, render_offscreen};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::SplatMode;
use smokeshadow::sim::{Particle, simulate};

fn render(
    scene: &Scene,
    particles: &[Particle],
    name: &str,
    channels: u32,
    spherical: bool,
) -> OffscreenFrame {
    render_offscreen(
        &gpu(),
        scene,
        particles,
        &technique(name, channels, scene.shadow.resolution_px, SplatMode::Point),
        &RenderOptions {
            spherical,
            ..RenderOptions::default()
        },
    )
    .wait()
    .unwrap()
}

#[test]
fn smoke_covers_the_pixels_where_particles_project_and_nothing_else() {
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let frame = render(&scene, &particles, "none", 1, true);
    let cam = CameraMatrices::new(&scene, W, H);
    let focal_px = H as f32 * 0.5 / (scene.camera.fov_y_deg.to_radians() * 0.5).tan();

    // Every visible particle (centre in view, not behind the box, above the ground) makes its
    // pixel at least as opaque as the particle alone would: 1 - exp(-τ·2r) on its central ray,
    // halved to allow for the ray through the pixel centre being off the particle centre.
    let mut checked = 0;
    for p in &particles {
        let Some(px) = cam.project_to_pixel(p.position, W, H) else {
            continue;
        };
        let (x, y) = (px.x as i64, px.y as i64);
        let hidden = scene
            .boxes
            .iter()
            .any(|b| segment_hits_box(cam.position, p.position, b));
        if x < 0 || y < 0 || x >= W as i64 || y >= H as i64 || hidden || p.position.y < p.radius_m {
            continue;
        }
        let own_alpha = 1.0 - (-p.density_per_m * 2.0 * p.radius_m).exp();
        let alpha = frame.hdr.get(x as u32, y as u32)[3];
        assert!(
            alpha >= 0.5 * own_alpha,
            "pixel ({x}, {y}) over particle at {} has alpha {alpha}, expected >= {}",
            p.position,
            0.5 * own_alpha
        );
        checked += 1;
    }
    assert!(
        checked > particles.len() / 2,
        "only {checked} particles were checkable"
    );

    // Pixels farther than any particle's projected radius (with a margin) have no smoke at all.
    let discs: Vec<(glam::Vec2, f32)> = particles
        .iter()
        .filter_map(|p| {
            let depth = (p.position - cam.position).dot(cam.forward);
            let px = cam.project_to_pixel(p.position, W, H)?;
            Some((px, p.radius_m * focal_px / depth.max(0.1) * 1.25 + 2.0))
        })
        .collect();
    let mut empty = 0;
    for y in 0..H {
        for x in 0..W {
            let c = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            if discs.iter().all(|(p, r)| p.distance(c) > *r) {
                let alpha = frame.hdr.get(x, y)[3];
                assert!(
                    alpha < 1e-3,
                    "pixel ({x}, {y}) is far from every particle but has alpha {alpha}"
                );
                empty += 1;
            }
        }
    }
    assert!(
        empty > (W * H / 4) as usize,
        "the plume should leave most of the sky empty ({empty})"
    );
}

#[test]
fn osm_darkens_the_side_away_from_the_light_and_the_ground_under_the_plume() {
    // Without the box, whose own shadow falls where the plume's does (tests/occluders.rs).
    let mut scene = reduced_plume();
    scene.boxes.clear();
    let particles = simulate(&scene);
    let lit = render(&scene, &particles, "none", 1, true);
    let shadowed = render(&scene, &particles, "osm", 24, true);
    let cam = CameraMatrices::new(&scene, W, H);

    // Smoke pixels (opaque enough in both) and the plume's horizontal extent on screen.
    let smoke: Vec<(u32, u32)> = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| lit.hdr.get(x, y)[3] > 0.6 && shadowed.hdr.get(x, y)[3] > 0.6)
        .collect();
    assert!(smoke.len() > 1000, "{} smoke pixels", smoke.len());
    let xs: Vec<u32> = smoke.iter().map(|p| p.0).collect();
    let (x_min, x_max) = (
        *xs.iter().min().unwrap() as f32,
        *xs.iter().max().unwrap() as f32,
    );
    let light_px = cam.project_to_pixel(scene.light.position, W, H).unwrap();
    assert!(
        light_px.x < x_min,
        "the thesis scene lights the plume from the left of the screen"
    );
    let ratio_in = |lo: f32, hi: f32| {
        let (mut sum_s, mut sum_l) = (0.0, 0.0);
        for &(x, y) in &smoke {
            let t = (x as f32 - x_min) / (x_max - x_min);
            if t >= lo && t <= hi {
                sum_s += luminance(shadowed.hdr.get(x, y));
                sum_l += luminance(lit.hdr.get(x, y));
            }
        }
        sum_s / sum_l
    };
    let near_side = ratio_in(0.0, 0.33);
    let far_side = ratio_in(0.67, 1.0);
    println!("osm/none luminance: light side {near_side:.3}, far side {far_side:.3}");
    assert!(
        near_side <= 1.0 + 1e-3 && far_side <= 1.0 + 1e-3,
        "shadows only remove light"
    );
    assert!(
        far_side < near_side * 0.85,
        "far side {far_side} is not darker than near side {near_side}"
    );

    // The ground where the light ray through the plume's centre of extinction lands is darker
    // with the shadow than without.
    let weight: f32 = particles
        .iter()
        .map(|p| p.density_per_m * p.radius_m.powi(3))
        .sum();
    let center = particles.iter().fold(Vec3::ZERO, |acc, p| {
        acc + p.position * p.density_per_m * p.radius_m.powi(3)
    }) / weight;
    let l = scene.light.position;
    let t = (l.y - scene.ground.height_m) / (l.y - center.y);
    let ground = l + (center - l) * t;
    let px = cam.project_to_pixel(ground, W, H).unwrap();
    let (gx, gy) = (px.x as u32, px.y as u32);
    assert!(
        gx < W && gy < H,
        "the plume's ground shadow at {ground} is in view"
    );
    assert!(
        lit.hdr.get(gx, gy)[3] < 0.05,
        "no smoke in front of the ground shadow point"
    );
    let (before, after) = (
        luminance(lit.hdr.get(gx, gy)),
        luminance(shadowed.hdr.get(gx, gy)),
    );
    println!("ground at {ground}: none {before:.4}, osm {after:.4}");
    assert!(
        after < 0.7 * before,
        "ground under the plume: {after} with osm vs {before} without"
    );
}

/// One particle sunk half into the ground, seen from slightly above: the column of pixels
/// through its centre runs from the sphere's top down to where it meets the ground.
fn sunk_particle_column(spherical: bool) -> Vec<f32> {
    let mut scene = Scene::thesis_plume();
    scene.output.width_px = 96;
    scene.output.height_px = 160;
    scene.boxes.clear();
    scene.camera.position = Vec3::new(0.0, 1.6, 6.0);
    scene.camera.target = Vec3::new(0.0, 0.2, 0.0);
    scene.camera.fov_y_deg = 30.0;
    let particle = Particle {
        position: Vec3::ZERO,
        velocity: Vec3::ZERO,
        age_s: 1.0,
        radius_m: 1.0,
        density_per_m: 3.0,
        albedo: Vec3::splat(0.8),
    };
    let frame = render(&scene, &[particle], "none", 1, spherical);
    (0..scene.output.height_px)
        .map(|y| frame.hdr.get(48, y)[3])
        .collect()
}

#[test]
fn spherical_billboards_fade_continuously_into_the_ground_and_flat_ones_step() {
    let max_step = |column: &[f32]| {
        column
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0f32, f32::max)
    };
    let soft = sunk_particle_column(true);
    let hard = sunk_particle_column(false);
    let peak = soft.iter().cloned().fold(0.0f32, f32::max);
    assert!(peak > 0.8, "the particle is dense: peak alpha {peak}");

    // Below the peak the column runs down to the contact line with the ground. With the fix the
    // chord shrinks to zero there, so alpha passes through intermediate values on its way to 0;
    // without it, the ground cuts the flat quad along a hard line: one jump from near the peak.
    let fade = |column: &[f32]| {
        let top = column.iter().position(|&a| a >= 0.95 * peak).unwrap();
        let bottom = column.iter().rposition(|&a| a > 1e-4).unwrap();
        let intermediate = column[top..=bottom]
            .iter()
            .filter(|&&a| a > 0.05 * peak && a < 0.9 * peak)
            .count();
        (intermediate, column[bottom], max_step(&column[top..]))
    };
    let (soft_mid, soft_last, soft_step) = fade(&soft);
    let (hard_mid, hard_last, hard_step) = fade(&hard);
    println!(
        "spherical: {soft_mid} intermediate pixels, last alpha {soft_last:.3}, max step {soft_step:.3}"
    );
    println!(
        "flat: {hard_mid} intermediate pixels, last alpha {hard_last:.3}, max step {hard_step:.3}"
    );
    assert!(
        soft_mid >= 6,
        "spherical fade has only {soft_mid} intermediate pixels"
    );
    assert!(
        soft_last < 0.1 * peak,
        "spherical alpha at the contact line {soft_last}"
    );
    assert!(soft_step < 0.3 * peak, "spherical max step {soft_step}");
    assert!(
        hard_mid == 0,
        "flat billboard has {hard_mid} intermediate pixels"
    );
    assert!(hard_last > 0.9 * peak, "flat alpha at the cut {hard_last}");
    assert!(hard_step > 0.9 * peak, "flat max step {hard_step}");
}

#[test]
fn rendering_is_deterministic() {
    let mut scene = reduced_plume();
    scene.output.width_px = 128;
    scene.output.height_px = 96;
    let particles = simulate(&scene);
    let a = render(&scene, &particles, "osm", 8, true);
    let b = render(&scene, &particles, "osm", 8, true);
    assert_eq!(a.image.as_raw(), b.image.as_raw());
}

#[test]
fn reused_shadow_maps_give_the_frame_a_fresh_build_gives() {
    // The viewer moves the camera without rebuilding the maps (they do not depend on it): the
    // picture must be the one a renderer that builds every frame draws.
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let mut moved = scene.clone();
    moved.camera.position += Vec3::new(3.0, 1.0, -1.0);
    let reuse = RenderOptions {
        reuse_shadow_maps: true,
        ..RenderOptions::default()
    };
    for name in ["osm", "exact", "has"] {
        let config = technique(name, 8, scene.shadow.resolution_px, SplatMode::Point);
        let mut renderer = smokeshadow::render::Renderer::new(
            &gpu,
            W,
            H,
            smokeshadow::render::OUTPUT_FORMAT,
            &config,
        )
        .wait()
        .unwrap();
        let target = smokeshadow::render::OffscreenTarget::new(&gpu, W, H);
        renderer
            .render(&gpu, &scene, &particles, &reuse, &target.view)
            .wait()
            .unwrap();
        renderer
            .render(&gpu, &moved, &particles, &reuse, &target.view)
            .wait()
            .unwrap();
        let times = renderer.gpu_times(&gpu).wait().unwrap();
        if name != "has" {
            // (Half-angle slicing's light passes are part of its particle pass: always there.)
            assert_eq!(
                times.get("shadow"),
                None,
                "{name}: the second frame rebuilt its maps"
            );
        }
        let reused = smokeshadow::gpu::read_texture_rgba8(&gpu, &target.texture)
            .wait()
            .unwrap();
        let fresh = render_offscreen(&gpu, &moved, &particles, &config, &RenderOptions::default())
            .wait()
            .unwrap()
            .image;
        // A fresh build sees the particles in the new camera's order; half-float maps add in
        // that order, so a few pixels may round differently by a step or two of 8 bits (the
        // order-independence test bounds T to 3e-3). Anything beyond is a stale map.
        let (mut differing, mut largest) = (0, 0u8);
        for (a, b) in reused.pixels().zip(fresh.pixels()) {
            let d =
                a.0.iter()
                    .zip(b.0)
                    .map(|(x, y)| x.abs_diff(y))
                    .max()
                    .unwrap();
            differing += usize::from(d > 0);
            largest = largest.max(d);
        }
        assert!(
            largest <= 2 && differing < (W * H / 200) as usize,
            "{name}: {differing} pixels differ, by up to {largest}/255"
        );
    }
}

#[test]
fn a_particle_around_the_eye_veils_every_pixel_by_its_closed_form() {
    // One big particle holding the camera off its centre, high above the ground, looking
    // level: every eye ray leaves the sphere, so every pixel must be veiled by
    // 1 - exp(-τ(1 - d/r)·(t_exit - t_near)), the closed form written here (d: the ray's
    // distance from the centre; the chord starts at the near plane, ends where the ray leaves
    // the sphere). A quad through the centre misses the rays that point away from it: before
    // the fix, the sixth of the frame on that side had no smoke at all.
    let mut scene = Scene::thesis_plume();
    scene.output.width_px = 96;
    scene.output.height_px = 72;
    scene.boxes.clear();
    let centre = Vec3::new(0.0, 30.0, 0.0);
    scene.camera.position = centre + Vec3::new(0.67, 0.0, 0.0);
    scene.camera.target = centre + Vec3::new(0.67, 0.0, -1.0);
    let (radius, tau) = (2.0f32, 0.6f32);
    let particle = Particle {
        position: centre,
        velocity: Vec3::ZERO,
        age_s: 1.0,
        radius_m: radius,
        density_per_m: tau,
        albedo: Vec3::splat(0.8),
    };
    let frame = render(&scene, &[particle], "none", 1, true);
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let camera = CameraMatrices::new(&scene, w, h);
    let world_from_clip = camera.clip_from_world().inverse();
    let mut worst = 0f32;
    for y in (0..h).step_by(7) {
        for x in (0..w).step_by(5) {
            let ndc = glam::Vec2::new(
                (x as f32 + 0.5) / w as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / h as f32 * 2.0,
            );
            let far = world_from_clip.project_point3(ndc.extend(1.0));
            let dir = (far - camera.position).normalize();
            let oc = centre - camera.position;
            let t_mid = oc.dot(dir);
            let d = (oc.length_squared() - t_mid * t_mid).max(0.0).sqrt();
            let t_exit = t_mid + (radius * radius - d * d).sqrt();
            let t_near = scene.camera.near_m / dir.dot(camera.forward);
            let expected = 1.0 - (-tau * (1.0 - d / radius) * (t_exit - t_near)).exp();
            let alpha = frame.hdr.get(x, y)[3];
            // Half-float alpha (1e-3) and the fragment's f32 chord: 0.01 is ample.
            worst = worst.max((alpha - expected).abs());
            assert!(
                (alpha - expected).abs() < 0.01,
                "pixel ({x}, {y}): alpha {alpha}, closed form {expected}"
            );
        }
    }
    assert!(worst < 0.01);
}

/// The bench's bound analysis counts what it claims (issue 14, section 5). Every map-building
/// technique draws the same light-facing billboards as the bench's cheapest build, so its build
/// runs the fragment shader as often per pass over them: `osm` and `fom` once, `dom` twice (its
/// start-depth pass draws the same spheres first, `dom_start_dilation` = 1) and `has` twice (its
/// build for the opaque pass, then every batch once in the particle pass). Each pass's channel
/// writes are its fragments times the components of its targets. No time is asserted.
#[test]
fn build_fragment_counts_are_whole_passes_over_the_cheapest_builds_billboards() {
    use smokeshadow::bench::{BenchOptions, bound::BuildWork};
    let gpu = gpu();
    assert!(
        gpu.has_pipeline_statistics(),
        "lavapipe counts fragment-shader invocations"
    );
    let options = BenchOptions {
        counts: vec![500],
        techniques: ["osm", "fom", "dom", "has"].map(str::to_owned).to_vec(),
        channels: 8,
        frames: 1,
        warmup: 0,
        particle_res: Default::default(),
        sorts: vec![Default::default()],
    };
    // DOM's start from the particles' own spheres (the paper's, and the tuned default): its
    // depth pass then draws the same billboards as its layers (set here whatever tune chooses).
    let mut scene = reduced_plume();
    scene
        .shadow
        .params
        .insert("dom_start_dilation".into(), 1.0.into());
    let results = smokeshadow::bench::run(&gpu, &scene, &options).unwrap();
    let count = &results.counts[0];
    let cheapest = count.cheapest.as_ref().unwrap();
    let floor = cheapest.work.unwrap().fragments;
    assert!(floor > 0);
    // One R16F channel, two bytes per fragment.
    assert_eq!(
        cheapest.work.unwrap(),
        BuildWork {
            fragments: floor,
            channel_writes: floor,
            bytes_written: 2 * floor,
        }
    );
    let work = |name: &str| -> BuildWork {
        let cell = count.cells.iter().find(|c| c.technique == name).unwrap();
        let m = cell.measured.as_ref().unwrap();
        let bound = m.bound.unwrap();
        assert!(bound.ns_per_fragment.is_finite() && bound.ns_per_fragment > 0.0);
        assert!(bound.over_cheapest.is_finite() && bound.over_cheapest > 0.0);
        assert_eq!(bound.cheapest_fragments, floor);
        m.build_work.unwrap()
    };
    // 8 slices in two RGBA16F targets.
    let osm = work("osm");
    assert_eq!((osm.fragments, osm.channel_writes), (floor, 8 * floor));
    assert_eq!(osm.bytes_written, 16 * floor);
    // 3 harmonics: 7 coefficients in two RGBA32F targets (the eighth channel blended too).
    let fom = work("fom");
    assert_eq!((fom.fragments, fom.channel_writes), (floor, 8 * floor));
    assert_eq!(fom.bytes_written, 32 * floor);
    // The start depth (one R16F channel), then 7 layers in two RGBA16F targets.
    let dom = work("dom");
    assert_eq!((dom.fragments, dom.channel_writes), (2 * floor, 9 * floor));
    // The opaque pass's light buffer, then the batches into it again: R16F both times.
    let has = work("has");
    assert_eq!((has.fragments, has.channel_writes), (2 * floor, 2 * floor));
}

#[test]
fn every_techniques_gpu_timestamps_agree_with_the_clock() {
    // The frame the sweep and bench report (GPU passes from timestamps, plus the CPU sort)
    // against the clock around the same render call (until its GPU work is done and the
    // timestamps are read): within CLOCK_TOLERANCE, the bound the commands warn beyond. Work
    // outside every timed pass (a submission the timer does not see, a dispatch lavapipe runs
    // outside its pass's pair) shows in every frame; other tests' load on a shared machine only
    // adds wall time, at random, so the frame that agrees best of two is the one held to it.
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let res = scene.shadow.resolution_px;
    let target = smokeshadow::render::OffscreenTarget::new(&gpu, W, H);
    let first = technique("none", 1, res, SplatMode::Segment);
    let mut renderer =
        smokeshadow::render::Renderer::new(&gpu, W, H, smokeshadow::render::OUTPUT_FORMAT, &first)
            .wait()
            .unwrap();
    let options = RenderOptions::default();
    for entry in smokeshadow::shadow::particle_techniques() {
        let config = technique(
            entry.name,
            entry.min_channels.max(16),
            res,
            SplatMode::Segment,
        );
        renderer.set_technique(&gpu, &config).wait().unwrap();
        // A warm-up frame: Mesa compiles its shaders.
        renderer
            .render(&gpu, &scene, &particles, &options, &target.view)
            .wait()
            .unwrap();
        gpu.wait_idle().unwrap();
        let mut frames = Vec::new();
        for _ in 0..2 {
            let start = std::time::Instant::now();
            let stats = renderer
                .render(&gpu, &scene, &particles, &options, &target.view)
                .wait()
                .unwrap();
            let times = renderer.gpu_times(&gpu).wait().unwrap();
            let wall_ms = start.elapsed().as_secs_f64() * 1e3;
            assert!(times.total_ms() > 0.0, "{}: no timestamps", entry.name);
            frames.push((stats.frame_ms(&times), wall_ms));
        }
        let (frame_ms, wall_ms) = frames
            .iter()
            .copied()
            .min_by(|a, b| {
                ((a.0 - a.1) / a.1)
                    .abs()
                    .total_cmp(&((b.0 - b.1) / b.1).abs())
            })
            .unwrap();
        println!(
            "{}: frame {frame_ms:.1} ms, wall {wall_ms:.1} ms",
            entry.name
        );
        assert_eq!(
            smokeshadow::gpu::clock_warning(
                entry.name,
                frame_ms,
                wall_ms,
                gpu.clock_floor_ms().wait()
            ),
            None,
            "{}: {frames:?}",
            entry.name
        );
    }
}
