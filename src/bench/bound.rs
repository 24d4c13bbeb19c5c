//! How far each technique's build is from the physical limit of building light-space maps
//! from particle billboards (issue 14, section 5).
//!
//! Every map-building technique draws the same light-facing billboards, one per particle, and
//! its fragment shader runs once per light texel each billboard covers. So a build costs
//!
//!   fragments x (the work per fragment: rasterising, the chord, the technique's own values)
//!   + fragments x channels x bytes (blending into its targets)
//!
//! and the bench measures each term's share (see [`Bound`]):
//! - **fragments**: the fragment-shader invocations of the technique's build passes, from
//!   pipeline-statistics queries ([`crate::gpu::FragmentTally`]); a technique with two passes
//!   over the billboards (`dom`'s start depth, `has`'s batches) counts both;
//! - **ns per fragment** and **ns per channel-write**: the build time divided by those counts
//!   and by fragments x channels of the targets (what its blending writes);
//! - **the cheapest build** ([`CheapestBuild`]): a single half-float channel, additive, over the
//!   same billboards at the same map resolution, each fragment adding its ray's optical depth.
//!   It is the floor: rasterising the billboards, finding each ray's chord through its
//!   sphere and one blended write. A technique's build over the cheapest is what its extra
//!   channels, passes and per-fragment arithmetic cost.
//!
//! The cheapest build is a bench-only pass, not a technique: it has no lookup, and the renderer
//! records it in place of a build ([`crate::render::Renderer::light_pass_frame`]).

use serde::Serialize;

use crate::sweep::Timing;
use smokeshadow_core::frame::gpu_data::BILLBOARD_VERTICES;
use smokeshadow_core::gpu::{FragmentTally, Gpu, MemoryLedger, TargetWrites};
use smokeshadow_core::shaders;
use smokeshadow_core::shadow::layered::{
    ADDITIVE, billboard_pipeline, cleared_attachment, map_texture,
};
use smokeshadow_core::shadow::{BuildInputs, ShadowError};

/// The name every build pass is timed and counted under.
pub const BUILD_PASS: &str = "shadow";

/// The cheapest build's one channel: a half float, as `osm`'s and `dom`'s maps and `has`'s
/// light buffer.
const CHEAPEST_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;

/// The cheapest possible build: one additive half-float channel over the light-facing
/// billboards (`shaders/bench/cheapest_build.wgsl`).
pub struct CheapestBuild {
    view: wgpu::TextureView,
    pipeline: wgpu::RenderPipeline,
    // Keeps the map's allocation on record, like a technique's.
    _memory: MemoryLedger,
}

impl CheapestBuild {
    /// Its map at `resolution_px`², drawn with group 0 of `frame_layout` (the renderer's).
    pub fn new(
        gpu: &Gpu,
        frame_layout: &wgpu::BindGroupLayout,
        resolution_px: u32,
    ) -> Result<Self, ShadowError> {
        let device = &gpu.device;
        let mut memory = MemoryLedger::for_device(&gpu.limits);
        let view = map_texture(
            &mut memory,
            device,
            "bench.cheapest",
            CHEAPEST_FORMAT,
            resolution_px,
        )?;
        let module = shaders::module(
            device,
            "bench.cheapest",
            &shaders::compose("bench/cheapest_build.wgsl", &[]),
        );
        let pipeline = billboard_pipeline(
            device,
            "bench.cheapest",
            &module,
            "fs_cheapest",
            &[Some(frame_layout)],
            &[CHEAPEST_FORMAT],
            ADDITIVE,
        );
        Ok(Self {
            view,
            pipeline,
            _memory: memory,
        })
    }

    /// Records the pass into the frame, timed and counted as a build.
    pub fn record(&self, inputs: BuildInputs<'_>) {
        let mut pass = inputs
            .encoder
            .begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("bench.cheapest"),
                color_attachments: &[cleared_attachment(&self.view, wgpu::Color::TRANSPARENT)],
                depth_stencil_attachment: None,
                timestamp_writes: inputs.timer.pass(BUILD_PASS),
                occlusion_query_set: None,
                multiview_mask: None,
            });
        let writes = TargetWrites::of(&[CHEAPEST_FORMAT]);
        inputs
            .timer
            .count_fragments(&mut pass, BUILD_PASS, writes, |pass| {
                // Group 0 only: the pass has no parameters of its own.
                if inputs.particle_count > 0 {
                    pass.set_pipeline(&self.pipeline);
                    pass.set_bind_group(0, inputs.frame_bind_group, &[]);
                    pass.set_vertex_buffer(0, inputs.particles.slice(..));
                    pass.draw(0..BILLBOARD_VERTICES, 0..inputs.particle_count);
                }
            });
    }
}

/// The fragment work of one frame's build passes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct BuildWork {
    /// Fragment-shader invocations over the build passes.
    pub fragments: u64,
    /// Σ invocations x channels of their pass's colour targets.
    pub channel_writes: u64,
    /// Σ invocations x bytes of their pass's colour targets.
    pub bytes_written: u64,
}

impl BuildWork {
    /// The build passes' counts among a frame's, if they were counted.
    pub fn of(tallies: &[FragmentTally]) -> Option<Self> {
        tallies.iter().find(|t| t.pass == BUILD_PASS).map(|t| Self {
            fragments: t.fragments,
            channel_writes: t.channel_writes,
            bytes_written: t.bytes_written,
        })
    }
}

/// The cheapest build at one particle count: its time and its work.
#[derive(Clone, Debug, Serialize)]
pub struct CheapestMeasured {
    pub build_ms: Timing,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work: Option<BuildWork>,
}

/// One technique's build against the limit, derived from its cell and the cheapest build at the
/// same count. Each quantity says what bounds it:
/// - `ns_per_fragment`: the build's time per fragment-shader invocation. Raster and shading
///   cost per fragment: a technique above the cheapest build's figure spends more arithmetic
///   per fragment (or more passes' set-up) than the floor;
/// - `ns_per_channel_write`: per blended channel. Blending and bandwidth cost per channel: a
///   technique with many channels that sits near the cheapest build's ns per fragment divided
///   by its channels is bound by its writes, not its arithmetic;
/// - `over_cheapest`: the build over the cheapest build. 1 would be the floor for this smoke at
///   this map resolution; its excess is what the technique's channels, passes and per-fragment
///   values cost.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Bound {
    pub build_ms: f64,
    pub fragments: u64,
    pub channel_writes: u64,
    pub bytes_written: u64,
    pub ns_per_fragment: f64,
    pub ns_per_channel_write: f64,
    pub cheapest_build_ms: f64,
    pub cheapest_fragments: u64,
    pub over_cheapest: f64,
}

impl Bound {
    /// The bound of a build of `build_ms` that did `work`, against `cheapest`; `None` when
    /// either was not counted or the build drew nothing.
    pub fn new(
        build_ms: f64,
        work: Option<BuildWork>,
        cheapest: &CheapestMeasured,
    ) -> Option<Self> {
        let work = work.filter(|w| w.fragments > 0 && w.channel_writes > 0)?;
        let floor = cheapest.work?;
        let cheapest_ms = cheapest.build_ms.median;
        let ns = build_ms * 1e6;
        Some(Self {
            build_ms,
            fragments: work.fragments,
            channel_writes: work.channel_writes,
            bytes_written: work.bytes_written,
            ns_per_fragment: ns / work.fragments as f64,
            ns_per_channel_write: ns / work.channel_writes as f64,
            cheapest_build_ms: cheapest_ms,
            cheapest_fragments: floor.fragments,
            over_cheapest: build_ms / cheapest_ms,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cheapest(ms: f64, fragments: u64) -> CheapestMeasured {
        CheapestMeasured {
            build_ms: Timing {
                median: ms,
                min: ms,
                max: ms,
            },
            work: Some(BuildWork {
                fragments,
                channel_writes: fragments,
                bytes_written: 2 * fragments,
            }),
        }
    }

    #[test]
    fn the_bound_divides_the_build_by_its_work_and_by_the_cheapest_build() {
        // 24 half-float channels over 1e6 fragments in 40 ms, the floor 10 ms.
        let work = BuildWork {
            fragments: 1_000_000,
            channel_writes: 24_000_000,
            bytes_written: 48_000_000,
        };
        let b = Bound::new(40.0, Some(work), &cheapest(10.0, 1_000_000)).unwrap();
        assert_eq!(b.ns_per_fragment, 40.0);
        assert!((b.ns_per_channel_write - 40.0 / 24.0).abs() < 1e-12);
        assert_eq!(b.over_cheapest, 4.0);
        assert_eq!(b.cheapest_fragments, 1_000_000);
    }

    #[test]
    fn no_bound_without_counts_or_fragments() {
        let floor = cheapest(10.0, 5);
        assert_eq!(Bound::new(1.0, None, &floor), None);
        assert_eq!(Bound::new(1.0, Some(BuildWork::default()), &floor), None);
        let uncounted = CheapestMeasured {
            work: None,
            ..floor.clone()
        };
        let work = BuildWork {
            fragments: 5,
            channel_writes: 5,
            bytes_written: 10,
        };
        assert_eq!(Bound::new(1.0, Some(work), &uncounted), None);
    }
}
