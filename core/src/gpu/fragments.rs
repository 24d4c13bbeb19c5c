//! Fragment counts of named passes from pipeline-statistics queries: how many times a pass's
//! fragment shader ran, and what those invocations wrote to its colour targets. The bench uses
//! them to set a build's time against the work it did (`crate::bench`, "bound").
//!
//! A pass opts in where it records its draws ([`super::GpuTimer::count_fragments`]), naming
//! what each fragment writes ([`TargetWrites`]); the counts of passes with the same name are
//! summed, like their times. Counting is off unless asked for
//! ([`super::GpuTimer::set_count_fragments`]) and needs `PIPELINE_STATISTICS_QUERY`; it never
//! runs in a timed frame of the bench, so it cannot perturb the times.
//!
//! What "fragment-shader invocations" counts is the driver's: Vulkan lets an implementation
//! count helper and discarded invocations, and llvmpipe shades 4x4 blocks, so on lavapipe the
//! count is the work the rasteriser handed to the shader (every lane of every partly covered
//! block it ran), not the texels covered. Comparing two passes over the same billboards on one
//! adapter is exact either way.

use super::{Gpu, GpuError};

/// What each fragment of a counted pass writes: the components of its colour targets (every
/// one is blended, the unused fourth channel of a 3-channel remainder included) and their bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TargetWrites {
    pub channels: u32,
    pub bytes: u32,
}

impl TargetWrites {
    /// The writes of a pass into colour targets of `formats`.
    pub fn of(formats: &[wgpu::TextureFormat]) -> Self {
        formats.iter().fold(Self::default(), |sum, f| Self {
            channels: sum.channels + u32::from(f.components()),
            bytes: sum.bytes + f.block_copy_size(None).unwrap_or(0),
        })
    }
}

/// One named pass's fragment work in one frame, summed over its recordings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FragmentTally {
    pub pass: &'static str,
    /// Fragment-shader invocations.
    pub fragments: u64,
    /// Σ invocations x channels of the recording's targets.
    pub channel_writes: u64,
    /// Σ invocations x bytes of the recording's targets.
    pub bytes_written: u64,
}

/// The query set and the buffer its counts resolve into, and the recordings of the frame being
/// recorded.
pub(super) struct FragmentCounter {
    query_set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    /// This frame's counted recordings, in query order.
    recorded: Vec<(&'static str, TargetWrites)>,
    /// The recordings of the frame last resolved into `resolve`.
    resolved: Vec<(&'static str, TargetWrites)>,
    capacity: u32,
}

impl FragmentCounter {
    /// A counter of up to `capacity` recordings a frame (the timer gives its own count of
    /// passes: half-angle slicing counts one per batch and pass), or `None` where the device has
    /// no pipeline-statistics queries.
    pub(super) fn new(gpu: &Gpu, capacity: u32) -> Option<Self> {
        if !gpu.has_pipeline_statistics() {
            return None;
        }
        Some(Self {
            query_set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("fragments.queries"),
                ty: wgpu::QueryType::PipelineStatistics(
                    wgpu::PipelineStatisticsTypes::FRAGMENT_SHADER_INVOCATIONS,
                ),
                count: capacity,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("fragments.resolve"),
                size: u64::from(capacity) * 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            recorded: Vec::new(),
            resolved: Vec::new(),
            capacity,
        })
    }

    pub(super) fn begin_frame(&mut self) {
        self.recorded.clear();
    }

    /// Counts the invocations of the draws `record` makes in `pass`.
    pub(super) fn count<'p>(
        &mut self,
        pass: &mut wgpu::RenderPass<'p>,
        name: &'static str,
        writes: TargetWrites,
        record: impl FnOnce(&mut wgpu::RenderPass<'p>),
    ) {
        let index = self.recorded.len() as u32;
        if index >= self.capacity {
            log::warn!("fragment counter full: pass {name} is not counted");
            record(pass);
            return;
        }
        self.recorded.push((name, writes));
        pass.begin_pipeline_statistics_query(&self.query_set, index);
        record(pass);
        pass.end_pipeline_statistics_query();
    }

    /// Resolves this frame's counts into the resolve buffer (after the frame's last pass).
    pub(super) fn resolve(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if self.recorded.is_empty() {
            return;
        }
        let count = self.recorded.len() as u32;
        encoder.resolve_query_set(&self.query_set, 0..count, &self.resolve, 0);
        self.resolved = std::mem::take(&mut self.recorded);
    }

    /// The counts of the frame last resolved, per pass name in first-recorded order (awaited
    /// until it finished); empty when it counted nothing.
    pub(super) async fn read(&mut self, gpu: &Gpu) -> Result<Vec<FragmentTally>, GpuError> {
        let resolved = std::mem::take(&mut self.resolved);
        if resolved.is_empty() {
            return Ok(Vec::new());
        }
        // Counting never runs in a timed frame, so the copy to a staging buffer is free to wait.
        let bytes = super::read_buffer(gpu, &self.resolve, 0, resolved.len() as u64 * 8).await?;
        let counts: Vec<u64> = bytes
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8-byte chunks")))
            .collect();
        Ok(tally(&resolved, &counts))
    }
}

/// Sums the counts of same-named recordings, weighting each by what its fragments write.
fn tally(recorded: &[(&'static str, TargetWrites)], counts: &[u64]) -> Vec<FragmentTally> {
    let mut out: Vec<FragmentTally> = Vec::new();
    for (&(pass, writes), &fragments) in recorded.iter().zip(counts) {
        let i = match out.iter().position(|t| t.pass == pass) {
            Some(i) => i,
            None => {
                out.push(FragmentTally {
                    pass,
                    ..FragmentTally::default()
                });
                out.len() - 1
            }
        };
        let t = &mut out[i];
        t.fragments += fragments;
        t.channel_writes += fragments * u64::from(writes.channels);
        t.bytes_written += fragments * u64::from(writes.bytes);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use wgpu::TextureFormat as F;

    #[test]
    fn target_writes_count_every_component_of_every_target() {
        // fom at 24 channels: 23 coefficients in five RGBA32F targets and one more RGBA32F (the
        // remainder of 3 is stored in RGBA), all blended.
        let fom = [F::Rgba32Float; 6];
        assert_eq!(
            TargetWrites::of(&fom),
            TargetWrites {
                channels: 24,
                bytes: 96
            }
        );
        assert_eq!(
            TargetWrites::of(&[F::Rgba16Float, F::Rg16Float]),
            TargetWrites {
                channels: 6,
                bytes: 12
            }
        );
        assert_eq!(
            TargetWrites::of(&[F::R16Float]),
            TargetWrites {
                channels: 1,
                bytes: 2
            }
        );
    }

    #[test]
    fn same_named_recordings_are_summed_with_their_own_writes() {
        // dom: a depth pass into one R16F channel, then the layers into 23 half floats.
        let depth = TargetWrites::of(&[F::R16Float]);
        let layers = TargetWrites::of(&[F::Rgba16Float; 6]);
        let recorded = [("shadow", depth), ("shadow", layers), ("other", depth)];
        let tallies = tally(&recorded, &[100, 90, 7]);
        assert_eq!(
            tallies,
            vec![
                FragmentTally {
                    pass: "shadow",
                    fragments: 190,
                    channel_writes: 100 + 90 * 24,
                    bytes_written: 200 + 90 * 48,
                },
                FragmentTally {
                    pass: "other",
                    fragments: 7,
                    channel_writes: 7,
                    bytes_written: 14,
                }
            ]
        );
    }
}
