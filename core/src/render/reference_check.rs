//! The reference checks itself: every run that measures against `exact` (render, probe, sweep,
//! compare, bench) first compares the light `exact` lets through at a few hundred of the frame's
//! shaded points with the f64 CPU closed form ([`crate::shadow::closed_form`]: the smoke's
//! transmittance times the opaque occluders' visibility), and refuses to report errors against a
//! reference that disagrees with it by more than [`TOLERANCE`] anywhere.
//!
//! The points are the ones a frame evaluates T at ([`super::shaded`]), spread over the image: a
//! lighting point of up to [`PARTICLE_POINTS`] particles taken evenly through the particle list
//! (rotating through each billboard's four), and up to [`OPAQUE_POINTS`] lit ground and box
//! points taken evenly from a grid over the image. Only points the light reaches are compared (a
//! spotlight's cone: outside it `exact` has no tiles and the lighting no light). A point whose
//! segment to the light grazes an occluder's edge within the exact test's epsilon is skipped
//! ([`crate::shadow::closed_form::Visibility::KnifeEdge`]) and counted.

use glam::Vec3;
use rayon::prelude::*;

use super::Renderer;
use super::shaded::{lit_opaque_points, particle_lighting_points};
use crate::frame::occluders;
use crate::gpu::Gpu;
use crate::scene::{LightKind, Scene};
use crate::shadow::closed_form::{self, Visibility};
use crate::shadow::light_space::LightSpace;
use crate::sim::Particle;

/// The largest difference in T allowed between the GPU reference and the CPU closed form: the
/// GPU's f32 chord arithmetic and 2^-26 fixed-point sum stay near 1e-5 (tests/techniques.rs).
pub const TOLERANCE: f64 = 1e-3;
/// The f64 mirror's march through a density volume: doubled until T at N and 2N steps agree
/// within this, up to this many steps (a point it cannot converge at reads NaN and fails).
pub const VOLUME_TOLERANCE: f64 = 1e-5;
pub const VOLUME_MAX_STEPS: u32 = 1 << 16;
/// Particle lighting points compared (one per particle, evenly through the list).
pub const PARTICLE_POINTS: usize = 200;
/// Lit opaque points compared (evenly through a grid over the image).
pub const OPAQUE_POINTS: usize = 200;
/// A density volume's eye samples compared (evenly through those of a grid over the image).
pub const VOLUME_POINTS: usize = 200;

/// What kind of surface a compared point lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointKind {
    Particle,
    Opaque,
    Volume,
}

impl PointKind {
    pub fn name(self) -> &'static str {
        match self {
            Self::Particle => "a particle's lighting point",
            Self::Opaque => "a lit ground or box point",
            Self::Volume => "an eye sample of the density volume",
        }
    }
}

/// The worst point of a check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorstPoint {
    pub point: Vec3,
    pub kind: PointKind,
    /// T (times the occluders' visibility) as the GPU reference computed it.
    pub gpu: f32,
    /// The same from the f64 closed form.
    pub cpu: f64,
}

/// The outcome of a passed check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceCheck {
    /// Points compared.
    pub points: usize,
    /// Of them, eye samples of a density volume (whose optical depth the f64 mirror marches,
    /// doubling its steps until T agrees within [`VOLUME_TOLERANCE`], or takes in closed form
    /// for a shape: `volume_closed_form`).
    pub volume_points: usize,
    pub volume_closed_form: bool,
    /// Points skipped as knife edges of the occluder test.
    pub knife_edges: usize,
    /// The largest |T_gpu − T_cpu| over the compared points (0 without points).
    pub worst_difference: f64,
    pub worst: Option<WorstPoint>,
}

impl std::fmt::Display for ReferenceCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "exact checked against the f64 closed form at {} shaded points: worst |ΔT| {:.1e} (allowed {:.0e})",
            self.points, self.worst_difference, TOLERANCE
        )?;
        if self.volume_points > 0 {
            write!(
                f,
                " ({} in the density volume; its optical depth {})",
                self.volume_points,
                match self.volume_closed_form {
                    true => "in closed form, a shape's chord",
                    false => "by an f64 march doubled until converged",
                }
            )?;
        }
        if self.knife_edges > 0 {
            write!(f, ", {} on an occluder's edge skipped", self.knife_edges)?;
        }
        Ok(())
    }
}

/// The points of a `width` x `height` frame of `scene` that the check compares, with their kinds
/// (`volume`: the frame's density volume, whose eye samples are compared too).
pub fn check_points(
    scene: &Scene,
    particles: &[Particle],
    (width, height): (u32, u32),
    volume: Option<&crate::medium::grid::DensityGrid>,
) -> Vec<(Vec3, PointKind)> {
    let camera = super::CameraMatrices::new(scene, width, height);
    let light = &scene.light;
    let axis = (light.target - light.position).normalize_or(Vec3::NEG_Y);
    let cos_cone = light.cone_angle_deg.to_radians().cos();
    let reached = |p: Vec3| {
        light.kind == LightKind::Point
            || (p - light.position).normalize_or_zero().dot(axis) >= cos_cone
    };
    let mut out = Vec::new();
    let stride = particles.len().div_ceil(PARTICLE_POINTS).max(1);
    for (k, i) in (0..particles.len()).step_by(stride).enumerate() {
        let corners = particle_lighting_points(camera.position, &particles[i..=i]);
        let p = corners[k % 4];
        if reached(p) {
            out.push((p, PointKind::Particle));
        }
    }
    // A grid of about 40 x 30 pixels over the image, of whose lit points OPAQUE_POINTS are kept.
    let stride_px = (width.max(height) / 40).max(1);
    let opaque = lit_opaque_points(scene, &camera, width, height, stride_px);
    let keep = opaque.len().div_ceil(OPAQUE_POINTS).max(1);
    out.extend(
        opaque
            .into_iter()
            .step_by(keep)
            .filter(|&p| reached(p))
            .map(|p| (p, PointKind::Opaque)),
    );
    if let (Some(grid), Some(spec)) = (volume, &scene.volume) {
        let samples = super::shaded::volume_eye_points(
            scene,
            &camera,
            grid,
            (width, height),
            stride_px,
            spec.eye_steps,
        );
        let keep = samples.len().div_ceil(VOLUME_POINTS).max(1);
        out.extend(
            samples
                .into_iter()
                .step_by(keep)
                .filter(|&p| reached(p))
                .map(|p| (p, PointKind::Volume)),
        );
    }
    out
}

/// Compares the light the renderer's technique lets through at the check's points (through
/// [`Renderer::probe_with_occluders`], the lighting's own functions) with the closed form. Run
/// with `exact` as the technique; any other stands for a broken reference (the tests do so).
/// Errs, in one line naming the worst point and both values, when they differ by more than
/// [`TOLERANCE`] anywhere.
pub async fn verify(
    renderer: &mut Renderer,
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
) -> anyhow::Result<ReferenceCheck> {
    let (width, height) = renderer.size();
    let grid = renderer.medium().grid().cloned();
    let points = check_points(scene, particles, (width, height), grid.as_deref());
    let positions: Vec<Vec3> = points.iter().map(|(p, _)| *p).collect();
    let gpu_t = renderer
        .probe_with_occluders(gpu, scene, particles, &positions)
        .await?;
    let far_m = LightSpace::faces_with(
        &scene.light,
        particles,
        renderer.medium().bounds(),
        scene.shadow.framing,
    )[0]
    .far_m;
    let epsilon_m = occluders::epsilon_m(scene.light.position, far_m);
    let light = scene.light.position;
    let cpu_t: Vec<Option<f64>> = positions
        .par_iter()
        .map(
            |&p| match closed_form::occluder_visibility(scene, light, p, epsilon_m) {
                Visibility::Lit => Some(mirror_transmittance(light, p, particles, grid.as_deref())),
                Visibility::Blocked => Some(0.0),
                Visibility::KnifeEdge => None,
            },
        )
        .collect();
    if let Some(i) = cpu_t.iter().position(|t| t.is_some_and(f64::is_nan)) {
        let p = positions[i];
        anyhow::bail!(
            "the reference's f64 mirror did not converge through the volume at ({:.3}, {:.3}, {:.3}) m within {VOLUME_MAX_STEPS} steps, so no error against `exact` is reported",
            p.x,
            p.y,
            p.z
        );
    }
    let check = ReferenceCheck {
        volume_closed_form: grid.as_ref().is_some_and(|g| g.analytic.is_some()),
        ..compare(&points, &gpu_t, &cpu_t)
    };
    match check.worst {
        Some(w) if check.worst_difference > TOLERANCE => Err(anyhow::anyhow!(
            "the reference `exact` disagrees with the f64 closed form at ({:.6}, {:.6}, {:.6}) m, {}: T = {:.6} on the GPU, {:.6} in closed form (|ΔT| {:.2e} > {:.0e} allowed), so no error against it is reported",
            w.point.x,
            w.point.y,
            w.point.z,
            w.kind.name(),
            w.gpu,
            w.cpu,
            check.worst_difference,
            TOLERANCE
        )),
        _ => Ok(check),
    }
}

/// The smoke's transmittance from `light` to `p` on the CPU in f64: the particles' closed form
/// and a density volume's optical depth, a shape's in closed form, a grid's by its march doubled
/// until T agrees within [`VOLUME_TOLERANCE`] (NaN where it does not within
/// [`VOLUME_MAX_STEPS`]).
pub fn mirror_transmittance(
    light: Vec3,
    p: Vec3,
    particles: &[Particle],
    volume: Option<&crate::medium::grid::DensityGrid>,
) -> f64 {
    let particles_tau = closed_form::optical_depth(light, p, particles);
    let volume_tau = volume.map_or(0.0, |grid| {
        if let Some(tau) = grid.closed_form_optical_depth(light.as_dvec3(), p.as_dvec3()) {
            return tau;
        }
        -grid
            .converged_transmittance(
                light.as_dvec3(),
                p.as_dvec3(),
                1,
                VOLUME_MAX_STEPS,
                VOLUME_TOLERANCE,
            )
            .map_or(f64::NAN, |c| c.transmittance)
            .ln()
    });
    closed_form::transmittance_of(particles_tau + volume_tau)
}

/// [`verify`] when the renderer's technique is the registry's reference, else nothing: the one
/// call every command makes after rendering a frame it may measure against.
pub async fn verify_if_reference(
    renderer: &mut Renderer,
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
) -> anyhow::Result<Option<ReferenceCheck>> {
    if renderer.technique().name() != crate::shadow::reference().name {
        return Ok(None);
    }
    verify(renderer, gpu, scene, particles).await.map(Some)
}

/// The check's numbers from the GPU's values and the closed form's (`None`: a knife edge).
pub fn compare(
    points: &[(Vec3, PointKind)],
    gpu_t: &[f32],
    cpu_t: &[Option<f64>],
) -> ReferenceCheck {
    let mut check = ReferenceCheck {
        points: 0,
        volume_points: 0,
        volume_closed_form: false,
        knife_edges: 0,
        worst_difference: 0.0,
        worst: None,
    };
    for ((&(point, kind), &gpu), &cpu) in points.iter().zip(gpu_t).zip(cpu_t) {
        let Some(cpu) = cpu else {
            check.knife_edges += 1;
            continue;
        };
        check.points += 1;
        check.volume_points += usize::from(kind == PointKind::Volume);
        let difference = (f64::from(gpu) - cpu).abs();
        // NaN from the GPU is the worst of all.
        if difference.is_nan() || difference > check.worst_difference || check.worst.is_none() {
            check.worst_difference = if difference.is_nan() {
                f64::INFINITY
            } else {
                difference
            };
            check.worst = Some(WorstPoint {
                point,
                kind,
                gpu,
                cpu,
            });
        }
    }
    check
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_worst_point_is_the_largest_difference_and_knife_edges_are_counted() {
        let points = [
            (Vec3::ZERO, PointKind::Particle),
            (Vec3::X, PointKind::Opaque),
            (Vec3::Y, PointKind::Opaque),
        ];
        let check = compare(&points, &[0.5, 0.0, 1.0], &[Some(0.5001), Some(0.75), None]);
        assert_eq!(check.points, 2);
        assert_eq!(check.knife_edges, 1);
        assert!((check.worst_difference - 0.75).abs() < 1e-12);
        let worst = check.worst.unwrap();
        assert_eq!(worst.point, Vec3::X);
        assert_eq!(worst.kind, PointKind::Opaque);
        // A NaN from the GPU is never hidden behind a finite difference.
        let nan = compare(&points[..2], &[0.5, f32::NAN], &[Some(0.5), Some(0.5)]);
        assert!(nan.worst_difference.is_infinite());
        assert_eq!(nan.worst.unwrap().point, Vec3::X);
    }
}
