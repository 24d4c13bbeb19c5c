//! The probe measures the opaque surfaces where the frame renders them: for every registered
//! particle technique, the T the frame's opaque pass gave the ground and the box (read back from
//! the HDR frame: its direct light against `none`'s, each less the ambient) equals the probe's T
//! at the same world points (`Renderer::probe_shaded` with no owner: what the sweep's RMS T
//! uses at those points)
//! within 0.01. (`has` once probed such a point through only the batches before it along the
//! half-angle axis, while the frame's opaque pass reads the light buffer after every batch: on
//! a box between the light and the smoke, the frame shows the smoke behind the box's lit face,
//! which that probe did not.)

use smokeshadow::Wait;
mod common;

use common::{REDUCED_H as H, REDUCED_W as W, gpu, luminance, reduced_plume};
use glam::Vec3;
use smokeshadow::render::shaded::first_opaque_hit;
use smokeshadow::render::{
    CameraMatrices, OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow::scene::{BoxShape, Scene};
use smokeshadow::shadow::closed_form;
use smokeshadow::sim::Particle;

/// Every `STRIDE`-th pixel of the reduced view is checked.
const STRIDE: u32 = 3;

/// How far the probe may be from the frame: the HDR target holds half floats (11 bits, so about
/// 5e-4 of each radiance), and only pixels whose direct light is at least a third of the total
/// are checked, so the ratio carries a few 1e-3 at most.
const TOLERANCE: f32 = 0.01;

fn config(scene: &Scene, name: &str, min_channels: u32) -> TechniqueConfig {
    TechniqueConfig {
        name: name.to_owned(),
        params: scene.shadow.params(8.max(min_channels)),
    }
}

/// The HDR frame of `scene` with `config`, as rows of RGBA.
fn frame(
    gpu: &smokeshadow::gpu::Gpu,
    scene: &Scene,
    particles: &[Particle],
    config: &TechniqueConfig,
) -> (Renderer, smokeshadow::gpu::Rgba16fImage) {
    let mut renderer = Renderer::new(gpu, W, H, OUTPUT_FORMAT, config)
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
        .unwrap();
    let hdr = smokeshadow::gpu::read_texture_rgba16f(gpu, renderer.hdr_texture())
        .wait()
        .unwrap();
    (renderer, hdr)
}

#[test]
fn the_probe_gives_the_t_the_opaque_pass_used_for_every_technique() {
    let gpu = gpu();
    let mut scene = reduced_plume();
    // The thesis' box beside the plume, and one between the light and the plume, in clear view
    // of the camera: the smoke lies behind its lit faces along the light.
    let towards_smoke = scene.light.target - scene.light.position;
    scene.boxes.push(BoxShape {
        center: scene.light.position + towards_smoke * 0.45,
        size: Vec3::splat(0.8),
        albedo: Vec3::splat(0.5),
    });
    let particles = smokeshadow::particles::scene_particles(&scene).unwrap();
    let none = config(&scene, "none", 1);
    let (_, lit) = frame(&gpu, &scene, &particles, &none);
    let mut dark = scene.clone();
    dark.light.intensity = 0.0;
    let (_, ambient) = frame(&gpu, &dark, &particles, &none);

    // Opaque points seen through pixel centres, where no smoke lies in front of them for the
    // camera (the frame's smoke opacity, alpha, is 0 in `none`'s frame, which draws the same
    // particles) and the direct light is at least a third of the pixel's radiance.
    let camera = CameraMatrices::new(&scene, W, H);
    let world_from_clip = camera.clip_from_world().inverse();
    let (mut pixels, mut points, mut direct) = (Vec::new(), Vec::new(), Vec::new());
    let mut on_box = 0;
    for y in (0..H).step_by(STRIDE as usize) {
        for x in (0..W).step_by(STRIDE as usize) {
            let ndc = glam::Vec2::new(
                (x as f32 + 0.5) / W as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / H as f32 * 2.0,
            );
            let dir =
                (world_from_clip.project_point3(ndc.extend(1.0)) - camera.position).normalize();
            let Some((point, normal)) = first_opaque_hit(&scene, camera.position, dir) else {
                continue;
            };
            let full = luminance(lit.get(x, y));
            let d = full - luminance(ambient.get(x, y));
            if lit.get(x, y)[3] > 0.0 || d < full / 3.0 {
                continue;
            }
            on_box += usize::from(normal != Vec3::Y);
            pixels.push((x, y));
            points.push(point);
            direct.push(d);
        }
    }
    let light = scene.light.position;
    let shadowed = points
        .iter()
        .filter(|&&p| closed_form::transmittance(light, p, &particles) < 0.8)
        .count();
    // Points in front of smoke along the light: clear to the light, smoke beyond them.
    let before_smoke = points
        .iter()
        .filter(|&&p| {
            let beyond = light + (p - light) * 4.0;
            closed_form::transmittance(light, p, &particles) > 0.99
                && closed_form::transmittance(light, beyond, &particles) < 0.9
        })
        .count();
    assert!(
        points.len() >= 200 && shadowed >= 20 && on_box >= 10 && before_smoke >= 10,
        "the check needs lit opaque points clear of smoke, some in its shadow, some on a box and \
         some with smoke beyond them along the light: {} points, {shadowed} with exact T < 0.8, \
         {on_box} on a box, {before_smoke} before smoke",
        points.len()
    );

    let no_owner = vec![smokeshadow::shadow::NO_OWNER; points.len()];
    for entry in smokeshadow::shadow::particle_techniques() {
        let config = config(&scene, entry.name, entry.min_channels);
        let (mut renderer, hdr) = frame(&gpu, &scene, &particles, &config);
        let probed = renderer
            .probe_shaded(&gpu, &scene, &particles, &points, &no_owner)
            .wait()
            .unwrap();
        let (mut worst, mut at) = (0.0f32, 0);
        for (j, &(x, y)) in pixels.iter().enumerate() {
            let rendered = (luminance(hdr.get(x, y)) - luminance(ambient.get(x, y))) / direct[j];
            let d = (rendered - probed[j]).abs();
            assert!(!d.is_nan(), "{}: no T at pixel ({x}, {y})", entry.name);
            if d > worst {
                (worst, at) = (d, j);
            }
        }
        let (x, y) = pixels[at];
        assert!(
            worst <= TOLERANCE,
            "{}: the frame's opaque pass used T {} at pixel ({x}, {y}) ({:?}), the probe gives {}",
            entry.name,
            (luminance(hdr.get(x, y)) - luminance(ambient.get(x, y))) / direct[at],
            points[at],
            probed[at]
        );
    }
}
