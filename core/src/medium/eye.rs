//! The eye's ray march through a density grid (`shaders/medium/eye_march.wgsl`), and
//! [`EyeMarchProbe`], which evaluates it at a list of rays with the light's transmittance by
//! secondary ray marching, so that `tests/medium.rs` can hold the shader to its f64 mirror
//! (`DensityGrid::march_eye`) and to the closed forms. The volume's eye pass in the frame will
//! call the same `march_eye` with the active technique's transmittance.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::gpu_grid::{GpuGrid, GridGpuError, GridProbe};
use crate::gpu::Gpu;
use crate::shaders;

/// Keep in sync with `EyeProbeParams` in shaders/medium/eye_march_probe.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct EyeProbeParams {
    light: [f32; 4],
    albedo: [f32; 4],
    eye_steps: u32,
    light_steps: u32,
    count: u32,
    jitter: f32,
}

/// Keep in sync with `EyeRay` in shaders/medium/eye_march_probe.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct EyeRayData {
    origin: [f32; 4],
    dir: [f32; 4],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            EyeProbeParams,
            "medium/eye_march_probe.wgsl",
            "EyeProbeParams",
            [light, albedo, eye_steps, light_steps, count, jitter]
        ),
        crate::mirror_layout!(
            EyeRayData,
            "medium/eye_march_probe.wgsl",
            "EyeRay",
            [origin, dir]
        ),
    ]
}

/// A ray of the probe: `origin + t·dir` for t in [`t_near`, `t_far`] (world metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeRay {
    pub origin: Vec3,
    /// A unit vector.
    pub dir: Vec3,
    pub t_near: f32,
    pub t_far: f32,
}

/// How the probe marches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeMarchSettings {
    pub light: Vec3,
    pub albedo: Vec3,
    pub eye_steps: u32,
    /// Samples towards the light from each eye sample (SRM's N).
    pub light_steps: u32,
    /// Where in its step each eye sample lies, 0..1.
    pub jitter: f32,
}

/// The march's radiance and transmittance along one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeResult {
    pub radiance: Vec3,
    pub transmittance: f32,
}

/// The eye-march probe's pipeline.
pub struct EyeMarchProbe {
    probe: GridProbe,
}

impl EyeMarchProbe {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            probe: GridProbe::new(
                gpu,
                "medium.eye_probe",
                "medium/eye_march_probe.wgsl",
                "eye_probe_main",
            ),
        }
    }

    /// The march along each of `rays` through `grid`. Refused where one invocation's loops
    /// (eye steps x (light steps + 4), plus 3 of set-up) would pass the adapter's loop budget.
    pub async fn march(
        &self,
        gpu: &Gpu,
        grid: &GpuGrid,
        settings: &EyeMarchSettings,
        rays: &[EyeRay],
    ) -> Result<Vec<EyeResult>, GridGpuError> {
        let loops = u64::from(settings.eye_steps) * (u64::from(settings.light_steps) + 4) + 3;
        if let Some(budget) = gpu.loop_budget()
            && loops > u64::from(budget)
        {
            return Err(GridGpuError::TooManyLoops {
                eye_steps: settings.eye_steps,
                light_steps: settings.light_steps,
                loops,
                budget,
            });
        }
        let params = EyeProbeParams {
            light: settings.light.extend(1.0).to_array(),
            albedo: settings.albedo.extend(0.0).to_array(),
            eye_steps: settings.eye_steps,
            light_steps: settings.light_steps,
            count: rays.len() as u32,
            jitter: settings.jitter,
        };
        let data: Vec<EyeRayData> = rays
            .iter()
            .map(|r| EyeRayData {
                origin: r.origin.extend(r.t_near).to_array(),
                dir: r.dir.extend(r.t_far).to_array(),
            })
            .collect();
        let bytes = self
            .probe
            .run(
                gpu,
                grid,
                bytemuck::bytes_of(&params),
                bytemuck::cast_slice(&data),
                rays.len(),
                16,
            )
            .await?;
        let values: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
        Ok(values
            .iter()
            .map(|v| EyeResult {
                radiance: Vec3::new(v[0], v[1], v[2]),
                transmittance: v[3],
            })
            .collect())
    }
}

/// The probe's composed shader module, for the naga validation test.
pub fn shader_modules() -> Vec<(String, String)> {
    vec![(
        "medium/eye_march_probe.wgsl".to_owned(),
        shaders::compose("medium/eye_march_probe.wgsl", &[]),
    )]
}
