//! Mixed-resolution particles (`--particle-res`, issue 14 §3): the smoke drawn at 1/2 and 1/4
//! of the frame's resolution and composited with the depth-aware upsample stays close to the
//! full-resolution frame, keeps its opacity in the HDR alpha, leaves the box's edges as sharp as
//! the opaque pass drew them, and draws a quarter (a sixteenth) of the fragments. On lavapipe,
//! at the reduced frame size; no timing is asserted.

use smokeshadow::Wait;
mod common;

use common::{
    REDUCED_H as H, REDUCED_W as W, error_lines, gpu, reduced_plume, segment_hits_box, smokeshadow,
    technique,
};
use glam::Vec3;
use smokeshadow::gpu::Gpu;
use smokeshadow::render::{
    CameraMatrices, OUTPUT_FORMAT, OffscreenTarget, ParticleRes, RenderOptions, Renderer,
};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::SplatMode;
use smokeshadow::sim::{Particle, simulate};

/// One frame at each resolution from one renderer: the sRGB image, the HDR frame and the
/// particle pass's fragment count.
struct Frame {
    image: image::RgbImage,
    hdr: smokeshadow::gpu::Rgba16fImage,
    fragments: Option<u64>,
}

fn frames(
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
    spherical: bool,
) -> Vec<(ParticleRes, Frame)> {
    let config = technique("osm", 8, 256, SplatMode::Point);
    let mut renderer = Renderer::new(gpu, W, H, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let target = OffscreenTarget::new(gpu, W, H);
    renderer.set_count_fragments(gpu, true);
    ParticleRes::ALL
        .into_iter()
        .map(|res| {
            let options = RenderOptions {
                spherical,
                particle_res: res,
                ..RenderOptions::default()
            };
            renderer
                .render(gpu, scene, particles, &options, &target.view)
                .wait()
                .unwrap();
            let rgba = smokeshadow::gpu::read_texture_rgba8(gpu, &target.texture)
                .wait()
                .unwrap();
            let frame = Frame {
                image: image::DynamicImage::ImageRgba8(rgba).into_rgb8(),
                hdr: smokeshadow::gpu::read_texture_rgba16f(gpu, renderer.hdr_texture())
                    .wait()
                    .unwrap(),
                fragments: renderer.particle_fragments(gpu).wait().unwrap(),
            };
            (res, frame)
        })
        .collect()
}

fn alpha_sum(frame: &Frame) -> f64 {
    (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .map(|(x, y)| f64::from(frame.hdr.get(x, y)[3]))
        .sum()
}

#[test]
fn lower_particle_resolutions_stay_close_to_full_keep_the_opacity_and_draw_fewer_fragments() {
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let frames = frames(&gpu, &scene, &particles, true);
    let full = &frames[0].1;
    let full_alpha = alpha_sum(full);
    assert!(
        full_alpha > 1000.0,
        "the plume covers the frame: {full_alpha}"
    );
    for (res, frame) in &frames[1..] {
        let flip = smokeshadow::diff::compare(&full.image, &frame.image)
            .unwrap()
            .metrics
            .flip_mean;
        let alpha = alpha_sum(frame);
        let (n, n_full) = (frame.fragments.unwrap(), full.fragments.unwrap());
        eprintln!(
            "particles at {res}: FLIP {flip:.5}, alpha {:.4} of full, fragments {:.4} of full",
            alpha / full_alpha,
            n as f64 / n_full as f64
        );
        // The smoke is soft: at 1/2 its billboards (4-20 px across at this size) lose little
        // in a bilinear reconstruction; 1/4 (64x48 texels here) blurs the thinnest wisps. FLIP
        // of this reduced 256x192 frame measured 0.0056 at 1/2 and 0.0146 at 1/4 (at 1024x768,
        // 0.0012 and 0.0023, against the target of 0.01 at 1/2); the bounds leave
        // about 40% for other CPUs' rounding.
        let bound = match res {
            ParticleRes::Half => 0.008,
            _ => 0.02,
        };
        assert!(flip <= bound, "particles at {res}: FLIP {flip} > {bound}");
        // The upsample filters premultiplied colour and alpha alike: the smoke's total opacity
        // stays (the tone map and the EXR's alpha rely on it; measured within 0.2%).
        assert!(
            (alpha / full_alpha - 1.0).abs() < 0.03,
            "particles at {res}: total alpha {alpha} against {full_alpha} at full resolution"
        );
        // Fragment shader invocations (pipeline statistics, which lavapipe has): a quarter of
        // the texels at 1/2, a sixteenth at 1/4, plus the partly covered 2x2 quads along the
        // billboards' edges, which weigh more the smaller the billboards: at 1024x768 the
        // thesis scene measured 0.29 and 0.094 of full resolution, at this reduced size
        // 0.37 and 0.167 (lavapipe's counts do not vary from run to run).
        let most = match res {
            ParticleRes::Half => 0.4,
            _ => 0.2,
        };
        assert!(
            (n as f64) <= most * n_full as f64,
            "particles at {res}: {n} fragments against {n_full} at full resolution"
        );
    }
    // Flat billboards (a hard depth test against the downsampled depth) go the same way.
    let flat = frames_flat_alpha(&gpu, &scene, &particles);
    assert!((flat.1 / flat.0 - 1.0).abs() < 0.05, "flat: {flat:?}");
}

fn frames_flat_alpha(gpu: &Gpu, scene: &Scene, particles: &[Particle]) -> (f64, f64) {
    let flat = frames(gpu, scene, particles, false);
    (alpha_sum(&flat[0].1), alpha_sum(&flat[1].1))
}

/// The camera ray's far point through the centre of pixel (x, y).
fn far_point(cam: &CameraMatrices, x: u32, y: u32) -> Vec3 {
    let ndc_x = (x as f32 + 0.5) / W as f32 * 2.0 - 1.0;
    let ndc_y = 1.0 - (y as f32 + 0.5) / H as f32 * 2.0;
    cam.clip_from_world()
        .inverse()
        .project_point3(Vec3::new(ndc_x, ndc_y, 1.0))
}

#[test]
fn the_box_edge_stays_as_sharp_as_the_opaque_pass_drew_it() {
    // A wall of smoke behind the box: beside the box's silhouette the smoke is in front of the
    // ground, on the box itself there is none in front. A plain bilinear upsample would bleed
    // that smoke over the box's edge for a texel or two.
    let gpu = gpu();
    let scene = reduced_plume();
    let bx = scene.boxes[0].clone();
    let cam = CameraMatrices::new(&scene, W, H);
    let away = (bx.center - cam.position).with_y(0.0).normalize();
    let side = away.cross(Vec3::Y);
    let mut particles = Vec::new();
    for i in -12..=12 {
        for j in 0..8 {
            let position = bx.center
                + away * (bx.size.length() * 0.5 + 1.2)
                + side * (i as f32 * 0.25)
                + Vec3::Y * (j as f32 * 0.25 - bx.size.y * 0.5 + 0.3);
            particles.push(Particle {
                position,
                velocity: Vec3::ZERO,
                age_s: 1.0,
                radius_m: 0.3,
                density_per_m: 4.0,
                albedo: Vec3::splat(0.9),
            });
        }
    }
    let frames = frames(&gpu, &scene, &particles, true);
    let full = &frames[0].1;
    let on_box = |x: u32, y: u32| segment_hits_box(cam.position, far_point(&cam, x, y), &bx);
    let alpha = |f: &Frame, x: u32, y: u32| f.hdr.get(x, y)[3];
    // Box pixels within 2 px of the silhouette, beside smoke (a neighbour off the box with
    // alpha), with none in front of them or of any box pixel the upsample's footprint reaches
    // (8 px at 1/4).
    let mut edge = Vec::new();
    for y in 8..H - 8 {
        for x in 8..W - 8 {
            if !on_box(x, y) || alpha(full, x, y) != 0.0 {
                continue;
            }
            let near = |r: i32| {
                (-r..=r).flat_map(move |dy| (-r..=r).map(move |dx| (x as i32 + dx, y as i32 + dy)))
            };
            let beside_smoke = near(2).any(|(nx, ny)| {
                !on_box(nx as u32, ny as u32) && alpha(full, nx as u32, ny as u32) > 0.05
            });
            let clear = near(8).all(|(nx, ny)| {
                !on_box(nx as u32, ny as u32) || alpha(full, nx as u32, ny as u32) == 0.0
            });
            if beside_smoke && clear {
                edge.push((x, y));
            }
        }
    }
    assert!(edge.len() >= 20, "only {} edge pixels to check", edge.len());
    for (res, frame) in &frames[1..] {
        let differ: Vec<&(u32, u32)> = edge
            .iter()
            .filter(|&&(x, y)| frame.hdr.get(x, y) != full.hdr.get(x, y))
            .collect();
        assert!(
            differ.is_empty(),
            "particles at {res}: {} of {} box pixels at the edge differ from full resolution, e.g. {:?}",
            differ.len(),
            edge.len(),
            &differ[..differ.len().min(5)]
        );
    }
}

#[test]
fn bad_particle_resolutions_and_has_below_full_are_refused_in_one_line() {
    for bad in ["1/3", "0", "abc"] {
        for command in ["render", "sweep", "bench"] {
            let out = smokeshadow(&[command, "--particle-res", bad]);
            assert_eq!(out.status.code(), Some(2), "{command} --particle-res {bad}");
            let lines = error_lines(&out);
            assert_eq!(lines.len(), 1, "{command} --particle-res {bad}: {lines:?}");
            assert!(
                lines[0].contains(bad) && lines[0].contains("1, 1/2, 1/4"),
                "{}",
                lines[0]
            );
        }
    }
    let png = common::scratch("mixed_res_has").join("has.png");
    let out = smokeshadow(&[
        "render",
        "-t",
        "has",
        "--particles",
        "50",
        "--size",
        "64x48",
        "--particle-res",
        "1/2",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let lines = error_lines(&out);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].contains("has draws its own particle pass"),
        "{}",
        lines[0]
    );
    assert!(!png.exists());
}

#[test]
fn the_registrys_particle_pass_owners_are_the_techniques_that_draw_it() {
    // The sweep skips cells below full resolution by the registry's `owns_particle_pass`, at
    // plan time; the renderer refuses by the technique's `particle_pass()`. They must agree.
    let gpu = gpu();
    let mut scene = reduced_plume();
    scene.output.width_px = 64;
    scene.output.height_px = 48;
    let scene = scene.with_particles(50).unwrap();
    let particles = smokeshadow::sim::simulate(&scene);
    let target = OffscreenTarget::new(&gpu, 64, 48);
    let first = technique("none", 1, 64, SplatMode::Point);
    let mut renderer = Renderer::new(&gpu, 64, 48, OUTPUT_FORMAT, &first)
        .wait()
        .unwrap();
    let options = RenderOptions {
        particle_res: ParticleRes::Half,
        ..RenderOptions::default()
    };
    for entry in smokeshadow::shadow::particle_techniques() {
        let config = technique(entry.name, entry.min_channels.max(8), 64, SplatMode::Point);
        renderer.set_technique(&gpu, &config).wait().unwrap();
        let refused = matches!(
            renderer
                .render(&gpu, &scene, &particles, &options, &target.view)
                .wait(),
            Err(smokeshadow::shadow::ShadowError::ParticleResUnsupported { .. })
        );
        assert_eq!(refused, entry.owns_particle_pass, "{}", entry.name);
    }
}
