//! The points whose transmittance a frame of the camera actually evaluates, so that a technique's
//! error against `exact` can be measured where it matters:
//! - every particle's four lighting points (the lighting pass evaluates T at a 2x2 grid across
//!   each camera-facing billboard, see `shaders/render/particle_lighting.wgsl`);
//! - the opaque surfaces (ground and boxes) seen through a grid of pixels, where the spotlight
//!   reaches them (inside its cone, facing it): the points that receive the smoke's shadow;
//! - a density volume's eye samples through the same grid of pixels (the middle of each step of
//!   the eye's march that has density, in front of the opaque surface; the frame jitters them by
//!   up to half a step), at most [`MAX_VOLUME_POINTS`] of them taken evenly.
//!
//! The transmittance at these points comes from [`super::Renderer::probe`]; [`rms_difference`]
//! turns two sets into the RMS transmittance error the tests, the probe and the sweep report.

use glam::{Vec2, Vec3};

use super::CameraMatrices;
use crate::medium::grid::DensityGrid;
use crate::scene::Scene;
use crate::sim::Particle;

/// Fraction of the radius at which the particle pass places its lighting points. Keep in sync
/// with `SHADE_OFFSET` in shaders/render/particle_lighting.wgsl and particles.wgsl.
pub const SHADE_OFFSET: f32 = 0.5;

/// The most eye samples of a density volume [`shaded_points`] keeps.
pub const MAX_VOLUME_POINTS: usize = 4096;

/// Pixel stride of the grid of pixels the opaque points and a volume's eye samples are taken
/// through when a technique's transmittance error is measured (the sweep, `tune`, the bench).
pub const SHADED_STRIDE_PX: u32 = 4;

/// The shaded points of a `width` x `height` view: particle lighting points, then lit opaque
/// points sampled every `stride_px` pixels, then the density volume's eye samples (`volume`:
/// the frame's grid, `Renderer::medium`) through the same pixels.
pub fn shaded_points(
    scene: &Scene,
    particles: &[Particle],
    (width, height): (u32, u32),
    stride_px: u32,
    volume: Option<&DensityGrid>,
) -> Vec<Vec3> {
    let camera = CameraMatrices::new(scene, width, height);
    let mut points = particle_lighting_points(camera.position, particles);
    points.extend(lit_opaque_points(scene, &camera, width, height, stride_px));
    if let (Some(grid), Some(spec)) = (volume, &scene.volume) {
        points.extend(volume_eye_points(
            scene,
            &camera,
            grid,
            (width, height),
            stride_px,
            spec.eye_steps,
        ));
    }
    points
}

/// The middles of the eye's march steps with density through a grid of pixels every
/// `stride_px`, up to the opaque surface (at most [`MAX_VOLUME_POINTS`], taken evenly).
pub fn volume_eye_points(
    scene: &Scene,
    camera: &CameraMatrices,
    grid: &DensityGrid,
    size: (u32, u32),
    stride_px: u32,
    eye_steps: u32,
) -> Vec<Vec3> {
    let index_from_world = grid.world_from_index.inverse();
    let origin = camera.position.as_dvec3();
    let mut out = Vec::new();
    for dir in pixel_rays(camera, size, stride_px) {
        let t_far = first_opaque_hit(scene, camera.position, dir)
            .map_or(f64::from(scene.camera.far_m), |(p, _)| {
                p.as_dvec3().distance(origin)
            });
        let dir = dir.as_dvec3();
        let a = origin + f64::from(scene.camera.near_m) * dir;
        let b = origin + t_far * dir;
        let Some((s0, s1)) = grid.support(
            index_from_world.transform_point3(a),
            index_from_world.transform_point3(b),
        ) else {
            continue;
        };
        let dt = (s1 - s0) / f64::from(eye_steps.max(1));
        for i in 0..eye_steps {
            let p = a.lerp(b, s0 + (f64::from(i) + 0.5) * dt);
            if grid.density_at_index(index_from_world.transform_point3(p)) > 0.0 {
                out.push(p.as_vec3());
            }
        }
    }
    let keep = out.len().div_ceil(MAX_VOLUME_POINTS).max(1);
    out.into_iter().step_by(keep).collect()
}

/// The unit directions from the camera through the centres of every `stride_px`-th pixel of a
/// `width` x `height` view, row by row.
fn pixel_rays(
    camera: &CameraMatrices,
    (width, height): (u32, u32),
    stride_px: u32,
) -> impl Iterator<Item = Vec3> + '_ {
    let world_from_clip = camera.clip_from_world().inverse();
    let stride = stride_px.max(1) as usize;
    (0..height).step_by(stride).flat_map(move |y| {
        (0..width).step_by(stride).map(move |x| {
            let ndc = Vec2::new(
                (x as f32 + 0.5) / width as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / height as f32 * 2.0,
            );
            (world_from_clip.project_point3(ndc.extend(1.0)) - camera.position).normalize()
        })
    })
}

/// The shaded points of `renderer`'s frame of `scene` ([`shaded_points`] at the renderer's
/// size, every [`SHADED_STRIDE_PX`], through the grid of the volume it loaded) with their owners
/// ([`point_owners`]): where the sweep, `tune` and the web page measure T
/// (`Renderer::probe_shaded`).
pub fn frame_points(
    renderer: &super::Renderer,
    scene: &Scene,
    particles: &[Particle],
) -> (Vec<Vec3>, Vec<u32>) {
    let points = shaded_points(
        scene,
        particles,
        renderer.size(),
        SHADED_STRIDE_PX,
        renderer.medium().grid().map(|g| &**g),
    );
    let owners = point_owners(particles.len(), points.len());
    (points, owners)
}

/// The owners of [`shaded_points`]' points for [`super::Renderer::probe_shaded`]: particle
/// `i`'s four lighting points come first, in particle order, then `total - 4 · particles`
/// opaque points that are no particle's (`shadow::NO_OWNER`).
pub fn point_owners(particles: usize, total: usize) -> Vec<u32> {
    (0..total)
        .map(|j| match j / 4 {
            i if i < particles => i as u32,
            _ => crate::shadow::NO_OWNER,
        })
        .collect()
}

/// The four lighting points of every particle seen from `eye`. Mirrors `billboard_frame` in
/// shaders/common/particle.wgsl.
pub fn particle_lighting_points(eye: Vec3, particles: &[Particle]) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(particles.len() * 4);
    for p in particles {
        let forward = (p.position - eye).normalize_or(Vec3::NEG_Z);
        let helper = if forward.y.abs() > 0.99 {
            Vec3::X
        } else {
            Vec3::Y
        };
        let right = forward.cross(helper).normalize();
        let up = right.cross(forward);
        let (r, u) = (
            right * (p.radius_m * SHADE_OFFSET),
            up * (p.radius_m * SHADE_OFFSET),
        );
        out.extend([
            p.position - r - u,
            p.position + r - u,
            p.position - r + u,
            p.position + r + u,
        ]);
    }
    out
}

/// Opaque surface points seen through pixel centres every `stride_px` pixels that the spotlight
/// lights (inside its cone and facing it).
pub fn lit_opaque_points(
    scene: &Scene,
    camera: &CameraMatrices,
    width: u32,
    height: u32,
    stride_px: u32,
) -> Vec<Vec3> {
    let light = &scene.light;
    let axis = (light.target - light.position).normalize();
    let cos_cone = light.cone_angle_deg.to_radians().cos();
    pixel_rays(camera, (width, height), stride_px)
        .filter_map(|dir| first_opaque_hit(scene, camera.position, dir))
        .filter(|&(point, normal)| {
            let to_point = (point - light.position).normalize();
            normal.dot(-to_point) > 0.0 && to_point.dot(axis) >= cos_cone
        })
        .map(|(point, _)| point)
        .collect()
}

/// The nearest hit of a ray with the ground square or a box: the point and its outward normal.
pub fn first_opaque_hit(scene: &Scene, origin: Vec3, dir: Vec3) -> Option<(Vec3, Vec3)> {
    let mut best: Option<(f32, Vec3)> = None;
    let g = &scene.ground;
    if dir.y.abs() > 1e-9 {
        let t = (g.height_m - origin.y) / dir.y;
        let p = origin + dir * t;
        let half = g.size_m * 0.5;
        if t > 0.0 && p.x.abs() <= half && p.z.abs() <= half && origin.y > g.height_m {
            best = Some((t, Vec3::Y));
        }
    }
    for b in &scene.boxes {
        let lo = b.center - b.size * 0.5;
        let hi = b.center + b.size * 0.5;
        let (mut t_near, mut t_far, mut normal) = (f32::NEG_INFINITY, f32::INFINITY, Vec3::ZERO);
        let mut missed = false;
        for axis in 0..3 {
            if dir[axis].abs() < 1e-12 {
                missed |= origin[axis] < lo[axis] || origin[axis] > hi[axis];
                continue;
            }
            let (mut t0, mut t1) = (
                (lo[axis] - origin[axis]) / dir[axis],
                (hi[axis] - origin[axis]) / dir[axis],
            );
            let mut n = Vec3::ZERO;
            n[axis] = -1.0;
            if t0 > t1 {
                std::mem::swap(&mut t0, &mut t1);
                n[axis] = 1.0;
            }
            if t0 > t_near {
                t_near = t0;
                normal = n;
            }
            t_far = t_far.min(t1);
        }
        if !missed && t_near <= t_far && t_near > 0.0 && best.is_none_or(|(t, _)| t_near < t) {
            best = Some((t_near, normal));
        }
    }
    best.map(|(t, n)| (origin + dir * t, n))
}

/// Root-mean-square difference of two equally long sets of values (0 for empty sets).
pub fn rms_difference(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len(), "RMS over sets of different sizes");
    if a.is_empty() {
        return 0.0;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum();
    (sum / a.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lighting_points_straddle_the_centre_across_the_view() {
        let p = Particle {
            position: Vec3::new(0.0, 1.0, 0.0),
            velocity: Vec3::ZERO,
            age_s: 0.0,
            radius_m: 2.0,
            density_per_m: 1.0,
            albedo: Vec3::ONE,
        };
        let eye = Vec3::new(0.0, 1.0, 10.0);
        let pts = particle_lighting_points(eye, &[p]);
        assert_eq!(pts.len(), 4);
        let mean = pts.iter().sum::<Vec3>() / 4.0;
        assert!((mean - p.position).length() < 1e-6);
        for q in &pts {
            // In the plane facing the eye, at radius·offset·√2 from the centre.
            assert!((q.z - p.position.z).abs() < 1e-6);
            assert!(((*q - p.position).length() - 2.0 * SHADE_OFFSET * 2f32.sqrt()).abs() < 1e-5);
        }
    }

    #[test]
    fn opaque_points_lie_on_lit_surfaces_in_the_cone() {
        let scene = Scene::thesis_plume();
        let camera = CameraMatrices::new(&scene, 128, 96);
        let pts = lit_opaque_points(&scene, &camera, 128, 96, 2);
        assert!(pts.len() > 200, "{} points", pts.len());
        let axis = (scene.light.target - scene.light.position).normalize();
        let cos_cone = scene.light.cone_angle_deg.to_radians().cos();
        for p in &pts {
            let on_ground = (p.y - scene.ground.height_m).abs() < 1e-3;
            let on_box = scene.boxes.iter().any(|b| {
                let d = (*p - b.center).abs() - b.size * 0.5;
                d.max_element().abs() < 1e-3
            });
            assert!(on_ground || on_box, "{p} is on no surface");
            assert!((*p - scene.light.position).normalize().dot(axis) >= cos_cone - 1e-6);
        }
    }

    #[test]
    fn rms_of_a_known_difference() {
        assert_eq!(rms_difference(&[1.0, 1.0], &[1.0, 1.0]), 0.0);
        let r = rms_difference(&[0.0, 0.0, 0.0, 0.0], &[0.5, -0.5, 0.5, -0.5]);
        assert!((r - 0.5).abs() < 1e-12);
    }
}
