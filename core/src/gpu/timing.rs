//! GPU pass times from timestamp queries.
//!
//! Each pass asks [`GpuTimer::pass`] for its `timestamp_writes`; the timer hands out a begin/end
//! query pair and remembers the pass name. Passes with the same name (a technique that draws in
//! several batches) are summed. On adapters without `TIMESTAMP_QUERY` every call returns `None`
//! and no time is reported: we never substitute CPU wall time for GPU time.
//!
//! **The frame is partitioned, not sampled.** [`GpuTimer::begin_frame`] submits an empty pass
//! whose timestamp starts the frame, on its own and before anything else of the frame, and each
//! pass, in the order the passes began on the GPU's clock, is charged from its own beginning to
//! the next pass's beginning (the last one: to the frame's last end); the span from the start
//! to the first pass is [`UPLOAD`]. The passes' times therefore add up to the whole span of the
//! frame, and work a driver runs outside its pass's own pair of timestamps is still counted, to
//! the pass it ran after. lavapipe does exactly that with compute dispatches: `exact`'s tile
//! lists ran after their pass's end timestamp (240 ms between the shadow passes and the
//! lighting), and `volume`'s voxelisation before its pass's beginning (600 ms after the frame's
//! start), so that each pass's own pair read 1-5 ms for 0.25-0.6 s of work. On a hardware GPU
//! the gaps between passes are the CPU's: a build that reads counts back mid-frame leaves the
//! GPU waiting, and that wait is its pass's. (With the start recorded in the frame's last
//! submission instead, an H200 read 62 ms of passes for `exact`'s 144 ms frame at a million
//! particles: the mid-frame submission and the CPU work before it ran before the start.)

use super::fragments::FragmentCounter;
use super::{FragmentTally, Gpu, GpuError, TargetWrites};

/// Most passes one frame may time, the frame's start included (two timestamps each: 4096, the
/// most queries one set may hold in wgpu): half-angle slicing records a lighting, an eye and a
/// light pass per slice, and under a point light one light pass per cube face, so
/// [`crate::shadow::half_angle::MAX_HAS_SLICES`] x (2 + 6) = 1,920 of them, beside the
/// occluders' and the builds' six faces.
pub const MAX_TIMED_PASSES: u32 = 2048;
const MAX_PASSES: u32 = MAX_TIMED_PASSES;

/// Name of the empty pass that marks the frame's start (not reported as a pass).
const FRAME_START: &str = "frame start";

/// The span from the frame's start (after the CPU sort) to its first pass: the CPU gathers the
/// sorted particles, uploads them and records the frame while the GPU waits, then the GPU copies
/// the upload. Reported as a pass of its own, so that no GPU pass is charged with it.
pub const UPLOAD: &str = "upload";

/// Name of the empty pass that marks the beginning of the frame's main encoder on the GPU's
/// clock: where [`UPLOAD`] ends when nothing ran before it (not reported as a pass).
const ENCODER_START: &str = "frame encoder start";

/// Records timestamp pairs around render/compute passes and reads them back.
pub struct GpuTimer {
    query_set: Option<wgpu::QuerySet>,
    resolve: Option<wgpu::Buffer>,
    /// Readback buffers, used in turn so that a frame can be resolved while earlier ones are
    /// still being mapped (the viewer polls without waiting).
    readbacks: Vec<Readback>,
    period_ns: f32,
    names: Vec<&'static str>,
    /// Fragment counts of the passes that opt in, while counting is on (the bench).
    fragments: Option<FragmentCounter>,
}

/// Milliseconds per named pass for one frame, in the order the passes were first recorded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PassTimes {
    pub passes: Vec<(&'static str, f64)>,
    /// Every pass as recorded (same-named passes apart), on the frame's own clock.
    pub spans: Vec<PassSpan>,
    /// The frame's start on the GPU's clock in milliseconds (comparable between the frames of
    /// one device, to lay them out on one timeline), when the frame has a start mark.
    pub start_ms: Option<f64>,
}

/// One recorded pass: its share of the frame's partition, from the frame's start.
#[derive(Clone, Debug, PartialEq)]
pub struct PassSpan {
    pub name: &'static str,
    pub start_ms: f64,
    pub ms: f64,
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

/// How far a frame's GPU time (its passes' timestamps, plus the CPU sort) may stray from the
/// clock's (the render call until its GPU work is done) before a command warns: a quarter of the
/// wall time. The partition above keeps them within a few percent on lavapipe at any scale
/// (measured 0.1-2.4% on thesis_plume and plume_65k, every technique); a gap beyond a quarter
/// means work outside every timed pass (a submission the timer does not see) or a CPU cost the
/// frame does not count.
pub const CLOCK_TOLERANCE: f64 = 0.25;

/// The warning a command prints in its table when a frame's GPU time `frame_ms` (timestamps plus
/// the CPU sort) and its wall time `wall_ms` disagree by more than [`CLOCK_TOLERANCE`] of the
/// wall time, once the clock's floor `floor_ms` ([`Gpu::clock_floor_ms`]: the round trip every
/// frame's wall time pays beyond its work) is added to the GPU time; `None` when they agree, or
/// when either is not a measurement (no timestamps).
pub fn clock_warning(what: &str, frame_ms: f64, wall_ms: f64, floor_ms: f64) -> Option<String> {
    if !(frame_ms.is_finite() && wall_ms.is_finite() && wall_ms > 0.0 && frame_ms > 0.0) {
        return None;
    }
    let floor_ms = if floor_ms.is_finite() {
        floor_ms.max(0.0)
    } else {
        0.0
    };
    let off = (frame_ms + floor_ms - wall_ms) / wall_ms;
    if off.abs() <= CLOCK_TOLERANCE {
        return None;
    }
    let why = if off < 0.0 {
        "the timestamps miss part of the frame's work (a pass or submission they do not cover, or \
         CPU time outside the sort); read the wall time"
    } else {
        "the timestamps add up to more than the clock, so their period or partition is wrong; \
         read the wall time"
    };
    Some(format!(
        "warning: {what}: GPU passes and CPU sort {frame_ms:.1} ms a frame, + {floor_ms:.2} ms \
         of a submission's round trip, the clock {wall_ms:.1} ms ({:+.0}%, beyond ±{:.0}%): {why}",
        off * 100.0,
        CLOCK_TOLERANCE * 100.0
    ))
}

/// Readback buffers in the ring: enough for the frames in flight of an interactive viewer.
const READBACKS: usize = 3;

struct Readback {
    buffer: wgpu::Buffer,
    state: ReadbackState,
}

enum ReadbackState {
    Free,
    /// Holds a resolved frame: its pass names, and once its mapping is asked for, the one-shot
    /// the mapping's callback answers (which [`GpuTimer::poll`] looks at without waiting and
    /// [`GpuTimer::read`] awaits).
    Resolved {
        names: Vec<&'static str>,
        mapped: Option<futures_channel::oneshot::Receiver<()>>,
        /// Order of resolution, to return the newest frame.
        serial: u64,
    },
}

impl GpuTimer {
    /// A timer that measures nothing (for work outside a timed frame).
    pub fn disabled() -> Self {
        Self {
            query_set: None,
            resolve: None,
            readbacks: Vec::new(),
            period_ns: 0.0,
            names: Vec::new(),
            fragments: None,
        }
    }

    pub fn new(gpu: &Gpu) -> Self {
        if !gpu.has_timestamps() {
            return Self::disabled();
        }
        let count = MAX_PASSES * 2;
        let size = u64::from(count) * 8;
        let readbacks = (0..READBACKS)
            .map(|_| Readback {
                buffer: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timer.readback"),
                    size,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                }),
                state: ReadbackState::Free,
            })
            .collect();
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
            readbacks,
            period_ns: gpu.queue.get_timestamp_period(),
            names: Vec::new(),
            fragments: None,
        }
    }

    /// Turns fragment counting on or off for the frames recorded from now on; returns whether
    /// it is on (it stays off where the adapter has no pipeline-statistics queries).
    pub fn set_count_fragments(&mut self, gpu: &Gpu, on: bool) -> bool {
        match (on, self.fragments.is_some()) {
            (false, _) => self.fragments = None,
            (true, false) => self.fragments = FragmentCounter::new(gpu, MAX_PASSES),
            (true, true) => {}
        }
        self.fragments.is_some()
    }

    /// Records the draws `record` makes in `pass`, counting their fragment-shader invocations
    /// under `name` while counting is on; `writes` is what each of them writes to the pass's
    /// colour targets. A pass that does not opt in is not counted.
    pub fn count_fragments<'p>(
        &mut self,
        pass: &mut wgpu::RenderPass<'p>,
        name: &'static str,
        writes: TargetWrites,
        record: impl FnOnce(&mut wgpu::RenderPass<'p>),
    ) {
        match &mut self.fragments {
            Some(counter) => counter.count(pass, name, writes, record),
            None => record(pass),
        }
    }

    /// The fragment counts of the last resolved frame, per pass name (awaited until it
    /// finished); empty when counting was off.
    pub async fn read_fragments(&mut self, gpu: &Gpu) -> Result<Vec<FragmentTally>, GpuError> {
        match &mut self.fragments {
            Some(counter) => counter.read(gpu).await,
            None => Ok(Vec::new()),
        }
    }

    /// Whether this timer measures anything.
    pub fn enabled(&self) -> bool {
        self.query_set.is_some()
    }

    /// Starts a new frame: forgets the previous frame's passes and submits the frame's start
    /// mark at once, in a submission of its own, so that it comes before every submission of
    /// the frame on the GPU's clock: the ones a build makes mid-frame (a readback of counts)
    /// too, which would otherwise run before a start recorded in the frame's last submission.
    pub fn begin_frame(&mut self, gpu: &Gpu) {
        self.names.clear();
        if let Some(counter) = &mut self.fragments {
            counter.begin_frame();
        }
        if self.enabled() {
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("timer.frame_start.encoder"),
                });
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("timer.frame_start"),
                timestamp_writes: self.compute_pass(FRAME_START),
            });
            gpu.queue.submit([encoder.finish()]);
        }
    }

    /// Marks the beginning of the frame's main encoder (after [`Self::begin_frame`]): the
    /// frame's upload ends there on the GPU's clock, unless a pass submitted mid-frame ran first.
    pub fn begin_encoder(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if self.enabled() {
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("timer.encoder_start"),
                timestamp_writes: self.compute_pass(ENCODER_START),
            });
        }
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

    /// One timed pass for a run of compute passes (one dispatch each, that must see each
    /// other's writes): [`Self::span_writes`] gives the run's first pass the start and its last
    /// the end.
    pub fn compute_span(&mut self, name: &'static str) -> Option<u32> {
        self.allocate(name)
    }

    /// Timestamp writes for a pass of a run from [`Self::compute_span`].
    pub fn span_writes(
        &self,
        span: Option<u32>,
        first: bool,
        last: bool,
    ) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let index = span?;
        if !first && !last {
            return None;
        }
        Some(wgpu::ComputePassTimestampWrites {
            query_set: self.query_set.as_ref()?,
            beginning_of_pass_write_index: first.then_some(index * 2),
            end_of_pass_write_index: last.then_some(index * 2 + 1),
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

    /// Resolves this frame's queries into a free readback buffer; call once, after the last
    /// pass. When every buffer still holds an unread frame (a viewer that never polls), the
    /// oldest is dropped.
    pub fn resolve(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(counter) = &mut self.fragments {
            counter.resolve(encoder);
        }
        let (Some(set), Some(resolve)) = (&self.query_set, &self.resolve) else {
            return;
        };
        if self.names.is_empty() {
            return;
        }
        let serial = self
            .readbacks
            .iter()
            .filter_map(|r| match &r.state {
                ReadbackState::Resolved { serial, .. } => Some(*serial + 1),
                ReadbackState::Free => None,
            })
            .max()
            .unwrap_or(0);
        let slot = match self
            .readbacks
            .iter()
            .position(|r| matches!(r.state, ReadbackState::Free))
        {
            Some(slot) => slot,
            None => {
                // All in use: reuse the oldest one that is not being mapped right now.
                let Some(slot) = self
                    .readbacks
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| {
                        matches!(r.state, ReadbackState::Resolved { mapped: None, .. })
                    })
                    .min_by_key(|(_, r)| match r.state {
                        ReadbackState::Resolved { serial, .. } => serial,
                        ReadbackState::Free => 0,
                    })
                    .map(|(i, _)| i)
                else {
                    return;
                };
                slot
            }
        };
        let count = self.names.len() as u32 * 2;
        encoder.resolve_query_set(set, 0..count, resolve, 0);
        let readback = &mut self.readbacks[slot];
        encoder.copy_buffer_to_buffer(resolve, 0, &readback.buffer, 0, u64::from(count) * 8);
        readback.state = ReadbackState::Resolved {
            names: self.names.clone(),
            mapped: None,
            serial,
        };
    }

    /// Awaits the newest resolved frame and returns its pass times (empty when timing is
    /// off). Older unread frames are discarded.
    pub async fn read(&mut self, gpu: &Gpu) -> Result<PassTimes, GpuError> {
        let Some(newest) = self.newest() else {
            return Ok(PassTimes::default());
        };
        for (i, r) in self.readbacks.iter_mut().enumerate() {
            if i != newest && matches!(r.state, ReadbackState::Resolved { mapped: None, .. }) {
                r.state = ReadbackState::Free;
            }
        }
        self.start_map(newest);
        gpu.wait_idle()?;
        if let ReadbackState::Resolved {
            mapped: Some(arrived),
            ..
        } = &mut self.readbacks[newest].state
        {
            arrived
                .await
                .map_err(|_| GpuError::Readback("the timestamps were not mapped".into()))?;
        }
        self.take(newest)
    }

    /// Without waiting: the newest frame whose times have arrived, if any; starts mapping the
    /// frames that are resolved. Call once per frame (the viewer).
    pub fn poll(&mut self, gpu: &Gpu) -> Option<PassTimes> {
        for i in 0..self.readbacks.len() {
            self.start_map(i);
        }
        let _ = gpu.device.poll(wgpu::PollType::Poll);
        let ready: Vec<usize> = (0..self.readbacks.len())
            .filter(|&i| match &mut self.readbacks[i].state {
                ReadbackState::Resolved {
                    mapped: Some(arrived),
                    ..
                } => matches!(arrived.try_recv(), Ok(Some(()))),
                _ => false,
            })
            .collect();
        let newest = ready
            .iter()
            .copied()
            .max_by_key(|&i| match self.readbacks[i].state {
                ReadbackState::Resolved { serial, .. } => serial,
                ReadbackState::Free => 0,
            })?;
        let mut out = None;
        for i in ready {
            let times = self.take(i).ok();
            if i == newest {
                out = times;
            }
        }
        out
    }

    fn newest(&self) -> Option<usize> {
        self.readbacks
            .iter()
            .enumerate()
            .filter_map(|(i, r)| match r.state {
                ReadbackState::Resolved { serial, .. } => Some((i, serial)),
                ReadbackState::Free => None,
            })
            .max_by_key(|(_, serial)| *serial)
            .map(|(i, _)| i)
    }

    /// Starts mapping readback `i` if it holds a frame not yet being mapped.
    fn start_map(&mut self, i: usize) {
        let r = &mut self.readbacks[i];
        if let ReadbackState::Resolved { names, mapped, .. } = &mut r.state
            && mapped.is_none()
        {
            let (tx, rx) = futures_channel::oneshot::channel();
            r.buffer.slice(..names.len() as u64 * 16).map_async(
                wgpu::MapMode::Read,
                move |result| {
                    if result.is_ok() {
                        let _ = tx.send(());
                    }
                },
            );
            *mapped = Some(rx);
        }
    }

    /// Reads mapped readback `i` (its mapping must have finished) and frees it.
    fn take(&mut self, i: usize) -> Result<PassTimes, GpuError> {
        let r = &mut self.readbacks[i];
        let ReadbackState::Resolved { names, .. } =
            std::mem::replace(&mut r.state, ReadbackState::Free)
        else {
            return Ok(PassTimes::default());
        };
        let slice = r.buffer.slice(..names.len() as u64 * 16);
        let ticks: Vec<u64> = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            bytemuck::cast_slice(&view).to_vec()
        };
        r.buffer.unmap();
        Ok(partition(&names, &ticks, self.period_ns))
    }
}

/// The frame's passes' times from their `[begin, end]` timestamp pairs (`ticks`, in recording
/// order), laid out in the order they began on the GPU's clock (a build's mid-frame submission
/// runs before passes recorded ahead of it): each pass from its beginning to the next pass's
/// beginning, or to the frame's last end for the last (the module's doc says why). With a frame
/// start, the time from it to the first pass or to the frame encoder's start mark is [`UPLOAD`]:
/// the CPU's gather and upload of the sorted particles and the recording of the frame, while
/// the GPU waits for them. The encoder's mark's own span (a driver's work before the next
/// pass's pair) is the next pass's.
fn partition(names: &[&'static str], ticks: &[u64], period_ns: f32) -> PassTimes {
    let (start, first) = match names.first() {
        Some(&FRAME_START) => (Some(ticks[1]), 1),
        _ => (None, 0),
    };
    let to_ms = |t: u64| t as f64 * f64::from(period_ns) / 1e6;
    let mut order: Vec<usize> = (first..names.len()).collect();
    // Stable: passes that began on the same tick keep their recording order.
    order.sort_by_key(|&k| ticks[2 * k]);
    let last_end = order.iter().map(|&k| ticks[2 * k + 1]).max().unwrap_or(0);
    // (name, begin) in time order, each mark's beginning handed to the pass after it.
    let mut runs: Vec<(&'static str, u64)> = Vec::with_capacity(order.len());
    let mut carried: Option<u64> = None;
    for &k in &order {
        let begin = ticks[2 * k];
        if names[k] == ENCODER_START {
            carried = Some(carried.unwrap_or(begin));
            continue;
        }
        runs.push((names[k], carried.take().unwrap_or(begin)));
    }
    let origin = start.or(runs.first().map(|r| r.1)).unwrap_or(0);
    let mut times = PassTimes {
        start_ms: start.map(to_ms),
        ..PassTimes::default()
    };
    let mut charge = |name: &'static str, begin: u64, end: u64| {
        let ms = to_ms(end.saturating_sub(begin));
        times.spans.push(PassSpan {
            name,
            start_ms: to_ms(begin.saturating_sub(origin)),
            ms,
        });
        match times.passes.iter_mut().find(|(n, _)| *n == name) {
            Some((_, total)) => *total += ms,
            None => times.passes.push((name, ms)),
        }
    };
    if let (Some(start), Some(&(_, begin))) = (start, runs.first()) {
        charge(UPLOAD, start, begin.max(start));
    }
    for (i, &(name, begin)) in runs.iter().enumerate() {
        let end = match runs.get(i + 1) {
            Some(&(_, next)) => next,
            None => last_end.max(begin),
        };
        charge(name, begin, end);
    }
    times
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_warning_fires_beyond_a_quarter_of_the_wall_time_either_way() {
        assert_eq!(clock_warning("osm", 100.0, 100.0, 0.0), None);
        assert_eq!(clock_warning("osm", 76.0, 100.0, 0.0), None);
        assert_eq!(clock_warning("osm", 124.0, 100.0, 0.0), None);
        // exact's timestamps once read 439 ms for a 24.4 s frame.
        let missed = clock_warning("exact", 439.0, 24_400.0, 0.0).unwrap();
        assert!(missed.starts_with("warning: exact: "), "{missed}");
        assert!(
            missed.contains("-98%") && missed.contains("miss part"),
            "{missed}"
        );
        let over = clock_warning("osm", 130.0, 100.0, 0.0).unwrap();
        assert!(
            over.contains("+30%") && over.contains("more than the clock"),
            "{over}"
        );
        assert!(!missed.contains("error"), "a warning, not an error line");
        // No timestamps, no comparison.
        assert_eq!(clock_warning("osm", 0.0, 100.0, 0.0), None);
        assert_eq!(clock_warning("osm", f64::NAN, 100.0, 0.0), None);
    }

    #[test]
    fn the_clock_floor_is_added_to_the_gpu_time_before_comparing() {
        // On the H200: 0.70 ms of passes and sort, 1.05 ms by the clock, 0.35 ms of it the
        // round trip of any submission.
        assert!(clock_warning("none", 0.70, 1.05, 0.0).is_some());
        assert_eq!(clock_warning("none", 0.70, 1.05, 0.35), None);
        // The floor does not hide work the timestamps miss: 62 ms against 144 ms.
        let missed = clock_warning("exact", 62.2, 144.2, 0.35).unwrap();
        assert!(
            missed.contains("+ 0.35 ms") && missed.contains("-57%"),
            "{missed}"
        );
        // Nor does it excuse timestamps that add up to more than the clock.
        assert!(clock_warning("osm", 100.0, 100.0, 30.0).is_some());
    }

    #[test]
    fn passes_partition_the_frame_from_its_start() {
        // A frame start at 100 ns; the frame's encoder begins at 500 (the upload, 100-500); work
        // the driver ran before the shadow pass's pair (500-700), the shadow pass's pair
        // (700-705), work after its end (705-900), the lighting (900-1000) and a tone map
        // (1000-1050); two more shadow passes by name.
        let names = [
            FRAME_START,
            ENCODER_START,
            "shadow",
            "shadow",
            "lighting",
            "tonemap",
        ];
        let ticks = [90, 100, 500, 500, 700, 705, 706, 710, 900, 1000, 1000, 1050];
        let times = partition(&names, &ticks, 1e6);
        assert_eq!(
            times.passes,
            vec![
                (UPLOAD, 400.0),
                ("shadow", 400.0),
                ("lighting", 100.0),
                ("tonemap", 50.0)
            ]
        );
        assert_eq!(times.total_ms(), 950.0);
        assert_eq!(times.get(FRAME_START), None);
        assert_eq!(times.get(ENCODER_START), None);
        assert_eq!(times.start_ms, Some(100.0));
        let spans: Vec<(f64, f64)> = times.spans.iter().map(|s| (s.start_ms, s.ms)).collect();
        assert_eq!(
            spans,
            vec![
                (0.0, 400.0),
                (400.0, 206.0),
                (606.0, 194.0),
                (800.0, 100.0),
                (900.0, 50.0)
            ]
        );
    }

    #[test]
    fn a_mid_frame_submission_is_charged_where_it_ran_with_the_wait_after_it() {
        // A build submits a count pass of its own while the frame is recorded (recorded after
        // the frame's encoder began, run before it: 200-210), then reads the counts back while
        // the GPU waits (210-600) before the frame's encoder runs (600-).
        let names = [FRAME_START, ENCODER_START, "shadow", "shadow", "tonemap"];
        let ticks = [0, 100, 600, 600, 650, 700, 200, 210, 700, 720];
        let times = partition(&names, &ticks, 1e6);
        assert_eq!(
            times.passes,
            vec![(UPLOAD, 100.0), ("shadow", 500.0), ("tonemap", 20.0)]
        );
        assert_eq!(
            times.total_ms(),
            620.0,
            "the frame from its start to its end"
        );
    }

    #[test]
    fn without_a_frame_start_the_first_pass_starts_at_its_own_beginning() {
        let names = ["shadow", "lighting"];
        let ticks = [10, 20, 30, 45];
        let times = partition(&names, &ticks, 2.0e6);
        assert_eq!(times.passes, vec![("shadow", 40.0), ("lighting", 30.0)]);
    }

    #[test]
    fn out_of_order_timestamps_give_zero_not_an_underflow() {
        // Passes that began before the frame's start (which cannot happen on one queue).
        let names = [FRAME_START, "a", "b"];
        let ticks = [0, 50, 40, 45, 30, 60];
        let times = partition(&names, &ticks, 1e6);
        assert_eq!(times.passes, vec![(UPLOAD, 0.0), ("b", 10.0), ("a", 20.0)]);
    }
}
