//! GPU pass times from timestamp queries.
//!
//! Each pass asks [`GpuTimer::pass`] for its `timestamp_writes`; the timer hands out a begin/end
//! query pair and remembers the pass name. Passes with the same name (a technique that draws in
//! several batches) are summed. On adapters without `TIMESTAMP_QUERY` every call returns `None`
//! and no time is reported: we never substitute CPU wall time for GPU time.

use super::{Gpu, GpuError};

/// Most passes one frame may time (half-angle slicing records two per slice).
const MAX_PASSES: u32 = 160;

/// Records timestamp pairs around render/compute passes and reads them back.
pub struct GpuTimer {
    query_set: Option<wgpu::QuerySet>,
    resolve: Option<wgpu::Buffer>,
    readback: Option<wgpu::Buffer>,
    period_ns: f32,
    names: Vec<&'static str>,
}

/// Milliseconds per named pass for one frame, in the order the passes were first recorded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PassTimes {
    pub passes: Vec<(&'static str, f64)>,
}

impl PassTimes {
    /// Time of one named pass, if it ran.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.passes
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, ms)| *ms)
    }

    /// Sum over all passes.
    pub fn total_ms(&self) -> f64 {
        self.passes.iter().map(|(_, ms)| ms).sum()
    }
}

impl GpuTimer {
    /// A timer that measures nothing (for work outside a timed frame).
    pub fn disabled() -> Self {
        Self {
            query_set: None,
            resolve: None,
            readback: None,
            period_ns: 0.0,
            names: Vec::new(),
        }
    }

    pub fn new(gpu: &Gpu) -> Self {
        if !gpu.has_timestamps() {
            return Self::disabled();
        }
        let count = MAX_PASSES * 2;
        let size = u64::from(count) * 8;
        Self {
            query_set: Some(gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timer.queries"),
                ty: wgpu::QueryType::Timestamp,
                count,
            })),
            resolve: Some(gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timer.resolve"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })),
            readback: Some(gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timer.readback"),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })),
            period_ns: gpu.queue.get_timestamp_period(),
            names: Vec::new(),
        }
    }

    /// Whether this timer measures anything.
    pub fn enabled(&self) -> bool {
        self.query_set.is_some()
    }

    /// Starts a new frame: forgets the previous frame's passes.
    pub fn begin_frame(&mut self) {
        self.names.clear();
    }

    /// Timestamp writes for a render pass named `name`, or `None` when timing is off or full.
    pub fn pass(&mut self, name: &'static str) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        let index = self.allocate(name)?;
        Some(wgpu::RenderPassTimestampWrites {
            query_set: self.query_set.as_ref()?,
            beginning_of_pass_write_index: Some(index * 2),
            end_of_pass_write_index: Some(index * 2 + 1),
        })
    }

    /// Timestamp writes for a compute pass named `name`.
    pub fn compute_pass(
        &mut self,
        name: &'static str,
    ) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let index = self.allocate(name)?;
        Some(wgpu::ComputePassTimestampWrites {
            query_set: self.query_set.as_ref()?,
            beginning_of_pass_write_index: Some(index * 2),
            end_of_pass_write_index: Some(index * 2 + 1),
        })
    }

    fn allocate(&mut self, name: &'static str) -> Option<u32> {
        self.query_set.as_ref()?;
        let index = self.names.len() as u32;
        if index >= MAX_PASSES {
            log::warn!("GPU timer full: pass {name} is not timed");
            return None;
        }
        self.names.push(name);
        Some(index)
    }

    /// Resolves this frame's queries into the readback buffer; call once, after the last pass.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let (Some(set), Some(resolve), Some(readback)) =
            (&self.query_set, &self.resolve, &self.readback)
        else {
            return;
        };
        if self.names.is_empty() {
            return;
        }
        let count = self.names.len() as u32 * 2;
        encoder.resolve_query_set(set, 0..count, resolve, 0);
        encoder.copy_buffer_to_buffer(resolve, 0, readback, 0, u64::from(count) * 8);
    }

    /// Waits for the frame and returns its pass times (empty when timing is off).
    pub fn read(&self, gpu: &Gpu) -> Result<PassTimes, GpuError> {
        let Some(readback) = &self.readback else {
            return Ok(PassTimes::default());
        };
        if self.names.is_empty() {
            return Ok(PassTimes::default());
        }
        let bytes = self.names.len() as u64 * 16;
        let slice = readback.slice(..bytes);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        gpu.wait_idle()?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let ticks: Vec<u64> = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            bytemuck::cast_slice(&view).to_vec()
        };
        readback.unmap();
        let mut times = PassTimes::default();
        for (i, name) in self.names.iter().enumerate() {
            let ns =
                ticks[2 * i + 1].saturating_sub(ticks[2 * i]) as f64 * f64::from(self.period_ns);
            let ms = ns / 1e6;
            match times.passes.iter_mut().find(|(n, _)| n == name) {
                Some((_, total)) => *total += ms,
                None => times.passes.push((name, ms)),
            }
        }
        Ok(times)
    }
}
