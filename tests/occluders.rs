//! GPU tests of the opaque occluders' shadows (core/src/frame/occluders.rs): the box shadows the
//! ground and the smoke, the same way under every technique and both occluder modes (`exact`
//! always tests the box exactly; the others do so by default, or read the filtered depth map
//! with `shadow.occluders = "map"`). They run on lavapipe in CI and fail, never skip, without
//! an adapter.

use smokeshadow::Wait;
mod common;

use common::{REDUCED_H as H, REDUCED_W as W, gpu, luminance, reduced_plume, segment_hits_box};
use glam::Vec3;
use smokeshadow::render::{
    CameraMatrices, OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer,
};
use smokeshadow::scene::{BoxShape, Scene};
use smokeshadow::shadow::{self, OccluderMode, SplatMode, closed_form};
use smokeshadow::sim::{Particle, simulate};

/// How far inside the box's shadow (and outside its silhouette from the camera) a checked point
/// must be, metres: the map's filter reaches two texels (3x3 bilinear taps) and its bias one and
/// a half, about 3 cm each at the box for the default 1024² map (16.5 m across at 11.6 m from
/// the light); 15 cm leaves the edge's penumbra well out of every check.
const MARGIN_M: f32 = 0.15;

fn grown(b: &BoxShape, by_m: f32) -> BoxShape {
    BoxShape {
        size: b.size + Vec3::splat(2.0 * by_m),
        ..b.clone()
    }
}

/// Whether the spotlight's full (inner-cone) intensity reaches `p`, away from the penumbra.
fn in_inner_cone(scene: &Scene, p: Vec3) -> bool {
    let l = &scene.light;
    let axis = (l.target - l.position).normalize();
    let inner = l.cone_angle_deg.to_radians() * (1.0 - l.penumbra);
    (p - l.position).normalize().dot(axis) > (0.9 * inner).cos()
}

/// The pixel `p` lands on, two pixels inside the frame, if it does.
fn pixel(cam: &CameraMatrices, p: Vec3) -> Option<(u32, u32)> {
    let px = cam.project_to_pixel(p, W, H)?;
    let inside = px.x >= 2.0 && px.y >= 2.0 && px.x < (W - 2) as f32 && px.y < (H - 2) as f32;
    inside.then_some((px.x as u32, px.y as u32))
}

/// Both ways the lighting can test the occluders.
const MODES: [OccluderMode; 2] = [OccluderMode::Exact, OccluderMode::Map];

/// A configuration of `name` with the occluders tested in `mode`.
fn config(name: &str, channels: u32, mode: OccluderMode) -> smokeshadow::render::TechniqueConfig {
    let mut config = common::technique(name, channels, 512, SplatMode::Segment);
    config.params.occluders = mode;
    config
}

/// Renders `scenes` in turn with one renderer of `name` with the occluders in `mode` (its
/// pipelines built once) and returns each frame's HDR pixels at `at`.
fn hdr_at(
    name: &str,
    mode: OccluderMode,
    scenes: &[(&Scene, &[Particle])],
    at: &[(u32, u32)],
) -> Vec<Vec<[f32; 4]>> {
    let gpu = gpu();
    let entry = shadow::find(name).unwrap();
    let config = config(name, entry.min_channels.max(8), mode);
    let mut renderer = Renderer::new(&gpu, W, H, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let target = OffscreenTarget::new(&gpu, W, H);
    scenes
        .iter()
        .map(|(scene, particles)| {
            renderer
                .render(
                    &gpu,
                    scene,
                    particles,
                    &RenderOptions::default(),
                    &target.view,
                )
                .wait()
                .unwrap();
            let hdr = smokeshadow::gpu::read_texture_rgba16f(&gpu, renderer.hdr_texture())
                .wait()
                .unwrap();
            at.iter().map(|&(x, y)| hdr.get(x, y)).collect()
        })
        .collect()
}

#[test]
fn the_box_shadows_the_ground_behind_it_under_every_technique() {
    let scene = reduced_plume();
    // The plume's own shadow falls across the box's; the smoke moves 3 m aside, across the
    // light's direction (horizontally), so that part of the box's shadow is clear of it.
    let light_dir = scene.light.target - scene.light.position;
    let aside = Vec3::new(light_dir.z, 0.0, -light_dir.x).normalize() * 3.0;
    let particles: Vec<Particle> = simulate(&scene)
        .into_iter()
        .map(|p| Particle {
            position: p.position + aside,
            ..p
        })
        .collect();
    let mut no_box = scene.clone();
    no_box.boxes.clear();
    let the_box = &scene.boxes[0];
    let light = scene.light.position;
    let cam = CameraMatrices::new(&scene, W, H);

    // Ground points deep in the box's shadow, in plain view of the camera, under the spotlight's
    // full intensity and away from the smoke (its exact T there above 0.9).
    let mut points = Vec::new();
    for ix in -60..=60 {
        for iz in -60..=60 {
            let p = Vec3::new(ix as f32 * 0.1, scene.ground.height_m, iz as f32 * 0.1);
            let shadowed = segment_hits_box(p, light, &grown(the_box, -MARGIN_M));
            let seen = !segment_hits_box(cam.position, p, &grown(the_box, MARGIN_M));
            if shadowed
                && seen
                && in_inner_cone(&scene, p)
                && closed_form::transmittance(light, p, &particles) > 0.9
                && let Some(px) = pixel(&cam, p)
            {
                points.push(px);
            }
        }
    }
    points.sort();
    points.dedup();
    assert!(
        points.len() >= 10,
        "only {} ground pixels deep in the box's shadow and clear of smoke",
        points.len()
    );

    // With the box, the direct light is gone: the ground there shows its albedo times the
    // ambient alone (the HDR target holds linear radiance; half floats carry 11 bits, so 1%).
    let g = scene.ground.albedo;
    let a = scene.shading.ambient;
    let ambient_only = [g.x * a.x, g.y * a.y, g.z * a.z];
    for (entry, mode) in shadow::particle_techniques().flat_map(|e| MODES.map(|m| (e, m))) {
        let frames = hdr_at(
            entry.name,
            mode,
            &[(&scene, &particles), (&no_box, &particles)],
            &points,
        );
        let name = format!("{} ({} occluders)", entry.name, mode.name());
        for ((&(x, y), with), without) in points.iter().zip(&frames[0]).zip(&frames[1]) {
            assert!(with[3] < 0.01, "{}: smoke in front of ({x}, {y})", name);
            for c in 0..3 {
                assert!(
                    (with[c] - ambient_only[c]).abs() <= 0.01 * ambient_only[c] + 1e-4,
                    "{}: ground at ({x}, {y}) behind the box has {:?}, not the ambient-only {:?}",
                    name,
                    with,
                    ambient_only
                );
            }
            // Without it the spotlight reaches the same ground: at least twice as bright (its
            // direct light is about five times the ambient there).
            assert!(
                luminance(*without) > 2.0 * luminance(*with),
                "{}: ground at ({x}, {y}) is not darker with the box: {} with, {} without",
                name,
                luminance(*with),
                luminance(*without)
            );
        }
    }
}

#[test]
fn a_particle_in_the_box_shadow_is_darker_than_the_same_particle_in_the_light() {
    let scene = reduced_plume();
    let the_box = scene.boxes[0].clone();
    let light = scene.light.position;
    let cam = CameraMatrices::new(&scene, W, H);
    let radius_m = 0.2;

    // A position behind the box as seen from the light, above the ground and seen by the camera
    // past the box's edge, with each of the particle's four lighting points (at half its radius)
    // deep in the shadow.
    let hidden = grown(&the_box, -MARGIN_M);
    let clear = grown(&the_box, radius_m + MARGIN_M);
    let mut found = None;
    'search: for ix in 0..40 {
        for iz in -20..20 {
            for iy in 0..6 {
                let p = the_box.center
                    + Vec3::new(ix as f32 * 0.1, iy as f32 * 0.1 - 0.4, iz as f32 * 0.1);
                let lit_points = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
                    .map(|(sx, sy)| p + Vec3::new(sx, sy, 0.0) * (0.5 * radius_m));
                if p.y > radius_m + 0.05
                    && lit_points
                        .iter()
                        .all(|&q| segment_hits_box(q, light, &hidden))
                    && !segment_hits_box(cam.position, p, &clear)
                    && in_inner_cone(&scene, p)
                    && pixel(&cam, p).is_some()
                {
                    found = Some(p);
                    break 'search;
                }
            }
        }
    }
    let position = found.expect("a position in the box's shadow the camera sees");
    let particle = Particle {
        position,
        radius_m,
        density_per_m: 5.0,
        albedo: Vec3::splat(0.9),
        velocity: Vec3::ZERO,
        age_s: 1.0,
    };
    let at = pixel(&cam, position).unwrap();
    let mut no_box = scene.clone();
    no_box.boxes.clear();
    // Dense enough (optical depth 2 across) that the pixel is mostly the particle's radiance,
    // thin enough that its own shadow leaves it some direct light.
    for (entry, mode) in shadow::particle_techniques().flat_map(|e| MODES.map(|m| (e, m))) {
        let frames = hdr_at(
            entry.name,
            mode,
            &[
                (&scene, std::slice::from_ref(&particle)),
                (&no_box, std::slice::from_ref(&particle)),
            ],
            &[at],
        );
        let name = format!("{} ({} occluders)", entry.name, mode.name());
        let (with, without) = (frames[0][0], frames[1][0]);
        assert!(with[3] > 0.6, "{}: the particle is not drawn", name);
        // In the shadow it scatters only the ambient light; in the light its direct light is
        // several times that.
        assert!(
            luminance(with) < 0.5 * luminance(without),
            "{}: the particle in the box's shadow has luminance {} against {} in the light",
            name,
            luminance(with),
            luminance(without)
        );
    }
}

#[test]
fn the_occluder_map_is_its_own_memory_at_the_scene_resolution() {
    let gpu = gpu();
    let mut scene = reduced_plume();
    let particles = simulate(&scene);
    let osm_map = config("osm", 8, OccluderMode::Map);
    let mut renderer = Renderer::new(&gpu, W, H, OUTPUT_FORMAT, &osm_map)
        .wait()
        .unwrap();
    let target = OffscreenTarget::new(&gpu, W, H);
    let technique_bytes = renderer.technique().memory().total_bytes();
    for side in [1024u64, 256] {
        // (8192² would be 256 MiB: the default 1024² is 4 MiB.)
        scene.shadow.occluder_resolution_px = side as u32;
        renderer
            .render(
                &gpu,
                &scene,
                &particles,
                &RenderOptions::default(),
                &target.view,
            )
            .wait()
            .unwrap();
        // A 32-bit depth per texel, and one box of two vec4s.
        assert_eq!(
            renderer.occluder_bytes(),
            side * side * 4 + 32,
            "occluder map at {side}²"
        );
        assert_eq!(renderer.technique().memory().total_bytes(), technique_bytes);
        assert_eq!(renderer.occluder_map_px(), Some(side as u32));
    }
    // The reference tests the boxes exactly even when asked for the map, and so does `osm` in
    // the default mode: their frames keep only the boxes (and a 1x1 placeholder for the
    // binding); switching back to the map brings it back.
    for (name, mode, side) in [
        ("exact", OccluderMode::Map, None),
        ("osm", OccluderMode::Exact, None),
        ("osm", OccluderMode::Map, Some(256u64)),
    ] {
        renderer
            .set_technique(&gpu, &config(name, 8, mode))
            .wait()
            .unwrap();
        renderer
            .render(
                &gpu,
                &scene,
                &particles,
                &RenderOptions::default(),
                &target.view,
            )
            .wait()
            .unwrap();
        assert_eq!(renderer.occluder_map_px(), side.map(|s| s as u32), "{name}");
        let map_bytes = side.map_or(4, |s| s * s * 4);
        assert_eq!(renderer.occluder_bytes(), map_bytes + 32, "{name}");
    }
}
