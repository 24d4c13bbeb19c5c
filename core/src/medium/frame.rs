//! The density volume in the frame: the scene's `[volume]` made into a grid and uploaded once
//! (again only when the volume's source changes), bound in group 0 beside the frame's uniforms
//! (`shaders/common/medium.wgsl`, bindings 4-6) so that the eye's march, the techniques' builds
//! and their lookups all read the same voxels. A scene without a volume binds one zero voxel.

use std::sync::Arc;

use glam::Vec3;

use super::gpu_grid::{GpuGrid, GridParams};
use super::grid::{DensityGrid, steps_per_voxel_length};
use super::scene::{VolumeError, VolumeSpec};
use crate::gpu::{Gpu, MemoryLedger, texture_3d_entry};

/// Group-0 binding of the volume's voxels (`shaders/common/frame.wgsl`). Its placement and the
/// frame's march settings ride in the frame's uniforms ([`FrameMedium::frame_params`]): a
/// uniform buffer of their own in group 0 crashes lavapipe (a segfault, not a validation error)
/// beside `avsm`'s.
pub const GRID_DENSITY_BINDING: u32 = 4;

const STAGES: wgpu::ShaderStages =
    wgpu::ShaderStages::VERTEX_FRAGMENT.union(wgpu::ShaderStages::COMPUTE);

/// The volume's group-0 layout entries, after the frame's own.
pub fn layout_entries() -> [wgpu::BindGroupLayoutEntry; 1] {
    [texture_3d_entry(
        GRID_DENSITY_BINDING,
        STAGES,
        wgpu::TextureSampleType::Float { filterable: false },
    )]
}

/// Loop iterations `exact`'s lookup keeps for its march through a density volume (its
/// particles' walk takes the rest of llvmpipe's budget), and the most steps that march may
/// take within them (3 go to the march's set-up).
pub const REFERENCE_LOOP_RESERVE: u32 = 2048;
pub const MAX_REFERENCE_STEPS: u32 = REFERENCE_LOOP_RESERVE - 3;

/// Steps of the reference's march towards the light through `grid`: four a voxel along the
/// grid's longest diagonal, or as many as the loop budget leaves ([`MAX_REFERENCE_STEPS`]) but
/// never fewer than two a voxel ([`steps_per_voxel_length`], so that no step skips a voxel;
/// [`least_reference_steps`]). Two a voxel left `exact` 4.0e-4 from the f64 march converged to
/// 1e-5 on the OpenUSD smoke; four, 6.5e-5 (9.3e-5 on the cloud, whose rest is f32 rounding).
pub fn reference_steps(grid: &DensityGrid) -> u32 {
    steps_per_voxel_length(2.0 * grid.dims.as_dvec3().length())
        .min(MAX_REFERENCE_STEPS)
        .max(least_reference_steps(grid))
}

/// The fewest steps the reference's march may take through `grid`: two a voxel along its
/// diagonal. A grid that needs more than [`MAX_REFERENCE_STEPS`] is refused.
pub fn least_reference_steps(grid: &DensityGrid) -> u32 {
    steps_per_voxel_length(grid.dims.as_dvec3().length())
}

/// The frame's volume, if the scene has one.
pub struct FrameMedium {
    /// What the uploaded grid was made from (its look-only fields reset: see [`grid_source`]).
    source: Option<VolumeSpec>,
    spec: Option<VolumeSpec>,
    grid: Option<Arc<DensityGrid>>,
    gpu_grid: GpuGrid,
    ledger: MemoryLedger,
    /// The grids made lately, by source, newest last (at most [`GRID_CACHE_BYTES`] of them): a
    /// cloud that moves makes a grid a frame, and an animated sweep renders every cell over
    /// the same frames, so each frame's grid is made once and uploaded again from here.
    made: Vec<(VolumeSpec, Arc<DensityGrid>)>,
}

/// The most bytes of grids [`FrameMedium`] keeps made (CPU memory: 64 grids of 128³).
const GRID_CACHE_BYTES: usize = 512 << 20;

/// The fields of `spec` that make the grid (not the march's steps nor the shading).
fn grid_source(spec: &VolumeSpec) -> VolumeSpec {
    let defaults = VolumeSpec::default();
    VolumeSpec {
        albedo: defaults.albedo,
        eye_steps: defaults.eye_steps,
        build_steps: defaults.build_steps,
        jitter: defaults.jitter,
        powder: defaults.powder,
        ..spec.clone()
    }
}

impl FrameMedium {
    /// No volume: one zero voxel bound.
    pub fn new(gpu: &Gpu) -> Result<Self, VolumeError> {
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let empty = DensityGrid::empty();
        let gpu_grid = GpuGrid::upload(gpu, &mut ledger, &empty)
            .map_err(|e| VolumeError::Upload(e.to_string()))?;
        Ok(Self {
            source: None,
            spec: None,
            grid: None,
            gpu_grid,
            ledger,
            made: Vec::new(),
        })
    }

    /// Makes the frame's volume `spec`'s: reads, bakes or voxelises and uploads its grid when
    /// its source changed, and keeps its march and shading settings for
    /// [`FrameMedium::frame_params`]. Returns whether the bindings changed (group 0 must be made
    /// again).
    pub async fn prepare(
        &mut self,
        gpu: &Gpu,
        spec: Option<&VolumeSpec>,
    ) -> Result<bool, VolumeError> {
        let source = spec.map(grid_source);
        let changed = source != self.source;
        if changed {
            let mut ledger = MemoryLedger::for_device(&gpu.limits);
            let made = source
                .as_ref()
                .and_then(|s| self.made.iter().find(|(m, _)| m == s))
                .map(|(_, g)| Arc::clone(g));
            let grid = match (spec, made) {
                (_, Some(grid)) => Some(grid),
                (Some(spec), None) => {
                    let grid = Arc::new(spec.density_grid(gpu, &mut ledger).await?);
                    self.remember(source.clone().expect("a spec has a source"), &grid);
                    Some(grid)
                }
                (None, None) => None,
            };
            // A new ledger: the grid's bytes only (the bake's transients are gone).
            let mut kept = MemoryLedger::for_device(&gpu.limits);
            if let Some(grid) = &grid
                && least_reference_steps(grid) > MAX_REFERENCE_STEPS
            {
                return Err(VolumeError::TooFine {
                    dims: grid.dims,
                    steps: least_reference_steps(grid),
                    max: MAX_REFERENCE_STEPS,
                });
            }
            let empty = DensityGrid::empty();
            self.gpu_grid = GpuGrid::upload(gpu, &mut kept, grid.as_deref().unwrap_or(&empty))
                .map_err(|e| VolumeError::Upload(e.to_string()))?;
            self.ledger = kept;
            self.grid = grid;
            self.source = source;
        }
        self.spec = spec.cloned();
        Ok(changed)
    }

    /// Keeps `grid`, made from `source`, forgetting the oldest beyond [`GRID_CACHE_BYTES`].
    fn remember(&mut self, source: VolumeSpec, grid: &Arc<DensityGrid>) {
        self.made.push((source, Arc::clone(grid)));
        let bytes = |m: &[(VolumeSpec, Arc<DensityGrid>)]| {
            m.iter().map(|(_, g)| 4 * g.values.len()).sum::<usize>()
        };
        while self.made.len() > 1 && bytes(&self.made) > GRID_CACHE_BYTES {
            self.made.remove(0);
        }
    }

    /// The grid's placement and the frame's march settings, for the frame's uniforms.
    pub fn frame_params(&self) -> GridParams {
        let spec = self.spec.clone().unwrap_or_default();
        GridParams {
            albedo_powder: spec.albedo.extend(spec.powder).to_array(),
            eye_steps: spec.eye_steps,
            jitter: spec.jitter,
            reference_steps: self.grid.as_deref().map_or(0, reference_steps),
            build_steps: spec.build_steps,
            ..self.gpu_grid.uniform
        }
    }

    /// The group-0 entry of the voxels.
    pub fn bind_entries(&self) -> [wgpu::BindGroupEntry<'_>; 1] {
        [wgpu::BindGroupEntry {
            binding: GRID_DENSITY_BINDING,
            resource: wgpu::BindingResource::TextureView(&self.gpu_grid.view),
        }]
    }

    /// The volume's grid (the CPU copy the reference's mirror reads), if the scene has one.
    pub fn grid(&self) -> Option<&Arc<DensityGrid>> {
        self.grid.as_ref()
    }

    /// The volume's settings, if the scene has one.
    pub fn spec(&self) -> Option<&VolumeSpec> {
        self.spec.as_ref()
    }

    /// The world box the volume's density can be non-zero in.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let (lo, hi) = self.grid.as_ref()?.world_bounds()?;
        Some((lo.as_vec3(), hi.as_vec3()))
    }

    /// The eye's march steps (0 without a volume).
    pub fn eye_steps(&self) -> u32 {
        match (&self.grid, &self.spec) {
            (Some(_), Some(spec)) => spec.eye_steps,
            _ => 0,
        }
    }

    /// Bytes the grid takes on the device.
    pub fn bytes(&self) -> u64 {
        self.ledger.total_bytes()
    }
}

/// The nearest and farthest distances from `from` to the box `lo`..`hi` (0 inside).
pub fn box_distances(from: Vec3, lo: Vec3, hi: Vec3) -> (f32, f32) {
    let near = from.clamp(lo, hi).distance(from);
    let far = (0..8)
        .map(|c| {
            let corner = Vec3::new(
                if c & 1 == 0 { lo.x } else { hi.x },
                if c & 2 == 0 { lo.y } else { hi.y },
                if c & 4 == 0 { lo.z } else { hi.z },
            );
            corner.distance(from)
        })
        .fold(0.0f32, f32::max);
    (near, far)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;

    #[test]
    fn box_distances_are_the_nearest_point_and_farthest_corner() {
        let (lo, hi) = (Vec3::new(1.0, -1.0, -1.0), Vec3::new(3.0, 1.0, 1.0));
        let (near, far) = box_distances(Vec3::ZERO, lo, hi);
        assert!((near - 1.0).abs() < 1e-6);
        assert!((far - (9.0f32 + 1.0 + 1.0).sqrt()).abs() < 1e-6);
        assert_eq!(box_distances(Vec3::new(2.0, 0.0, 0.0), lo, hi).0, 0.0);
    }

    #[test]
    fn reference_steps_take_four_a_voxel_along_the_diagonal_or_what_the_budget_leaves() {
        let grid = DensityGrid {
            dims: UVec3::new(3, 4, 12),
            values: vec![0.0; 144],
            world_from_index: glam::DAffine3::IDENTITY,
            density_scale_per_m: 1.0,
            analytic: None,
        };
        // The diagonal is 13 voxels long.
        assert_eq!(reference_steps(&grid), 52);
        assert_eq!(least_reference_steps(&grid), 26);
        // 600.002 voxels along the diagonal: 2,401 steps do not fit, 1,201 do.
        let wide = DensityGrid {
            dims: UVec3::new(600, 1, 1),
            values: Vec::new(),
            ..grid
        };
        assert_eq!(reference_steps(&wide), MAX_REFERENCE_STEPS);
        assert_eq!(least_reference_steps(&wide), 1201);
    }
}
