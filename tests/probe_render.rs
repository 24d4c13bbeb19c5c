//! The probe measures what the frame renders: for every registered technique, the smoke's T that
//! the particle lighting actually used at each particle's four lighting points (read back from
//! the lighting buffer, `Renderer::lit_particles`) equals the probe's T at the same points
//! (`Renderer::probe_shaded`, which the sweep's RMS T column uses) within 1e-3. (`has` lights a
//! particle's four points from its particle's batch; its probe once gave each point the batches
//! before the point's own half-angle key, and differed by up to 0.2 there.)

use smokeshadow::Wait;
mod common;

use std::collections::HashMap;

use glam::Vec3;
use smokeshadow::render::shaded::{particle_lighting_points, point_owners};
use smokeshadow::render::{
    CameraMatrices, OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow::scene::Scene;

const W: u32 = 160;
const H: u32 = 120;

#[test]
fn the_probe_gives_the_t_the_particle_lighting_used_for_every_technique() {
    let gpu = common::gpu();
    let mut scene = Scene::thesis_plume();
    scene.output.width_px = W;
    scene.output.height_px = H;
    let particles = smokeshadow::particles::scene_particles(&scene).unwrap();
    // (Particles with the same sphere have the same lighting: each gets it.)
    let mut index: HashMap<(u32, u32, u32, u32), Vec<usize>> = HashMap::new();
    for (i, p) in particles.iter().enumerate() {
        index
            .entry(key(p.position, p.radius_m))
            .or_default()
            .push(i);
    }
    let eye = CameraMatrices::new(&scene, W, H).position;
    let target = OffscreenTarget::new(&gpu, W, H);
    for entry in smokeshadow::shadow::particle_techniques() {
        let config = TechniqueConfig {
            name: entry.name.to_owned(),
            params: scene.shadow.params(8.max(entry.min_channels)),
        };
        let mut renderer = Renderer::new(&gpu, W, H, OUTPUT_FORMAT, &config)
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
        let lit = renderer.lit_particles(&gpu).wait().unwrap();
        assert_eq!(
            lit.len(),
            particles.len(),
            "{}: every particle is lit",
            entry.name
        );
        // The frame's lighting points, in the original particle order, and their lit T.
        let mut lit_t = vec![[f32::NAN; 4]; particles.len()];
        for l in &lit {
            for &i in &index[&key(l.center, l.radius_m)] {
                lit_t[i] = l.transmittance;
            }
        }
        let points = particle_lighting_points(eye, &particles);
        let owners = point_owners(particles.len(), points.len());
        let probed = renderer
            .probe_shaded(&gpu, &scene, &particles, &points, &owners)
            .wait()
            .unwrap();
        let (mut worst, mut at) = (0.0f32, 0);
        for (j, &t) in probed.iter().enumerate() {
            let d = (t - lit_t[j / 4][j % 4]).abs();
            assert!(!d.is_nan(), "{}: no T at point {j}", entry.name);
            if d > worst {
                (worst, at) = (d, j);
            }
        }
        assert!(
            worst <= 1e-3,
            "{}: the probe gives T = {} at lighting point {at} ({}), the frame's lighting used {}",
            entry.name,
            probed[at],
            points[at],
            lit_t[at / 4][at % 4]
        );
        // The frame lit the smoke: not every point is in full light.
        let darkest = probed.iter().copied().fold(1.0f32, f32::min);
        if entry.name != "none" {
            assert!(darkest < 0.5, "{}: darkest T {darkest}", entry.name);
        }
    }
}

/// A particle's identity for matching the lighting buffer's order to the particles': its
/// centre's and radius' bits (the instances are copies of them).
fn key(p: Vec3, r: f32) -> (u32, u32, u32, u32) {
    (p.x.to_bits(), p.y.to_bits(), p.z.to_bits(), r.to_bits())
}
