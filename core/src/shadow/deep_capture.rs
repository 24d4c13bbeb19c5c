//! The deep capture: every light-space particle fragment's chord segment stored per texel and
//! merged into the texel's sorted nodes (z, Ω(z)) of the piecewise-linear optical depth, the
//! uncompressed deep shadow map (Lokovic & Veach 2000; thesis 3.3.3.1) that `dsm` and `avsm`
//! compress (see `deep_nodes.rs`).
//!
//! Four passes, all in shaders/shadow/deep_capture.wgsl: a count raster pass over the
//! light-space billboards (a count per texel: additive blending into a float target where the
//! adapter blends 32-bit floats, `counts_by_blending`, else atomics), a prefix scan into list
//! offsets, a fill pass writing each fragment's segment (z0, z1, optical depth, draw index) into
//! its texel's list, and the resolve's compute passes, as the owner asks ([`Resolve`]): for
//! `dsm`, it splits each segment into two events, its start (z0, slope) and its end (z1,
//! −slope), and sorts them by depth — a total key over what is sorted, so the nodes do not
//! depend on the order the fragments arrived in; a merge sort: runs of 16 sorted in registers,
//! then eight runs merged a pass ([`merge_passes`]), in read-write storage textures
//! (`KEY_TEXTURES`) — whose last pass turns them into the nodes (z, Ω(z)), written to a texture
//! of their own (`NODE_FORMAT`); for `avsm`, it sorts the segments by (z0, z1, optical depth,
//! draw index) (`avsm` sorted) or by draw index (`avsm` streaming), which restores the order the
//! particles were drawn in, the order an engine's interlocked fragment shader would see them.
//! The counts are read back before the fill so the lists can grow to hold the frame (a CPU–GPU
//! sync per build).
//! A compression pass then binds [`DeepCapture::layout`] as its group 1
//! (shaders/shadow/deep_capture_lists.wgsl declares it) and reads the sorted segments or nodes.
//!
//! **Bands.** When the frame's segments would not fit one storage binding (`avsm`'s segments and
//! nodes take 16 bytes a segment each, so 8.4M segments under a 128 MiB limit: 1,000,000
//! particles at 512² capture 12.7M; `dsm` bands alike, `max_band_segments`), the map is
//! captured in bands of whole rows, each holding as many segments as fit: the
//! fill (scissored to the band), the resolve and the owner's compression run once per band over
//! the same lists, every band but the last in a submission of its own (each band's parameters
//! are a queue write, which lands at the next submission). One band when everything fits; only
//! a single row of more segments than a binding holds is refused.
//!
//! **The loop limit.** llvmpipe ends every shader loop after 65,535 iterations of an invocation
//! group (all the shader's loops together: a cut loop just exits, and the texel's list is left
//! half sorted or half compressed). The resolve and the compressions are one invocation per
//! texel looping over its list, so they run in **rounds**: dispatches of one pass, each bound
//! to its round index ([`Rounds`], a uniform at a dynamic offset) and doing a slice of the work
//! sized so that it loops at most `loop_budget` times ([`Gpu::loop_budget`]: 60,000 on llvmpipe,
//! unbounded elsewhere, where every pass is one round). `dsm`'s merge sort takes a round per
//! merge pass (each loops about 2n times over a list's 2n events); the resolve's heapsorts
//! (`avsm`'s segments) run [`sifts_per_round`] sifts a round; a compression says how many rounds
//! it needs ([`super::deep_nodes::DeepNodesSpec::rounds`]). The single-pass steps (a merge pass,
//! a greedy fit) loop a little over 2n times, so a list longer than [`longest_list`] (a little
//! under half the budget) is refused ([`ShadowError::TexelListTooLong`]); the counter
//! `max_texel_list` reports the longest.

use bytemuck::{Pod, Zeroable};

use super::ShadowError;
use super::layered::{VolumeBuild, billboard_pipeline, cleared_attachment, draw_particles};
use crate::gpu::uniform_entry;
use crate::gpu::{
    AllocationError, Gpu, GpuTimer, MemoryLedger, ROW_TEXELS, bind_entry, read_buffer,
    row_texture_descriptor, row_texture_size, storage_descriptor, storage_entry,
    storage_texture_entry, texture_binding,
};
use crate::shaders;

/// Keep in sync with `CaptureParams` in shaders/shadow/deep_capture_lists.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct CaptureParams {
    resolution: u32,
    capacity: u32,
    row_begin: u32,
    row_end: u32,
    band_base: u32,
    max_list: u32,
    loop_budget: u32,
    _pad: u32,
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        CaptureParams,
        "shadow/deep_capture_lists.wgsl",
        "CaptureParams",
        [
            resolution,
            capacity,
            row_begin,
            row_end,
            band_base,
            max_list,
            loop_budget
        ]
    )]
}

/// Bytes per stored segment (z0, z1, optical depth, draw index) and per segment's share of the
/// resolved nodes (2 per segment, (z, Ω) each).
pub const SEGMENT_BYTES: u64 = 16;
pub const NODE_BYTES_PER_SEGMENT: u64 = 16;
/// The loop budget where the adapter sets none ([`Gpu::loop_budget`]): no limit worth splitting
/// for.
const UNBOUNDED_LOOP_BUDGET: u32 = 1 << 30;
/// Most rounds one pass may take (the round uniform holds this many indices).
const MAX_ROUNDS: u32 = 256;

/// Sifts per round of the resolve's heapsorts (mirrors `sifts_per_round` in
/// shaders/shadow/deep_capture.wgsl): a sift takes at most log2(n) + 1 iterations.
pub fn sifts_per_round(max_list: u32, loop_budget: u32) -> u32 {
    let depth = max_list.max(1).ilog2() + 3;
    (loop_budget / depth).max(1)
}

/// Keys per run of the merge sort of `dsm`'s events (`RUN` in shaders/shadow/deep_capture.wgsl).
const RUN: u32 = 16;
/// The two-run levels one merge pass makes (`WAY_LEVELS`: eight runs merged).
const WAY_LEVELS: u32 = 3;

/// The merge passes of the events of a list of `n` segments (mirrors `runs_of` in
/// shaders/shadow/deep_capture.wgsl): the 2n events' two-run levels are ceil(log2) of their
/// runs of `RUN`, and a pass makes `WAY_LEVELS` of them (eight runs merged), the last pass
/// what is left over. Never fewer for a longer list, so the longest sets the rounds.
pub fn merge_passes(n: u32) -> u32 {
    merge_levels(2 * n).div_ceil(WAY_LEVELS)
}

/// The two-run merge levels over `events` in runs of `RUN`: ceil(log2) of the runs (`levels_for`
/// in shaders/shadow/deep_capture.wgsl).
fn merge_levels(events: u32) -> u32 {
    let runs = events.div_ceil(RUN);
    if runs <= 1 { 0 } else { (runs - 1).ilog2() + 1 }
}

/// The longest texel list a capture accepts under `loop_budget`: one dispatch must stay within
/// the budget, and 2n + ceil(2n / RUN) bounds every single pass over a list of n segments (2n
/// events): a merge pass loops once per event and once per group of at least two runs (for a
/// SIMD group of invocations too, whose lanes' lists differ in length: every list's pass cuts
/// its groups at the same indices, so the longest list's loops cover the others'), the run
/// sort once per run (its loads and sorting network are unrolled), a greedy fit 2n + N + 2
/// times (N <= 16 nodes, under ceil(2n / RUN) for any list near the limit), `avsm`'s insertion
/// sort and the prefix it reads first 2n + 2·(n/16 - 1) + 2, for a SIMD group too (one flat
/// loop: the group loops as often as its busiest lane).
pub fn longest_list(loop_budget: u32) -> u32 {
    let events = u64::from(loop_budget.saturating_sub(1)) * u64::from(RUN) / u64::from(RUN + 1);
    u32::try_from(events / 2).unwrap_or(u32::MAX)
}

/// Rounds of one heapsort phase over lists of at most `max_list`: the build sifts n/2 starts,
/// the extraction n - 1 ends.
fn heap_rounds(max_list: u32, loop_budget: u32) -> (u32, u32) {
    let c = sifts_per_round(max_list, loop_budget);
    (
        (max_list / 2).div_ceil(c).max(1),
        max_list.saturating_sub(1).div_ceil(c).max(1),
    )
}
/// The textures of a resolve into nodes (`dsm`'s): the sort keys (its events' depths and
/// changes of slope) on two sides, one after the other, between which the merge passes alternate
/// (which side a pass reads is then an index offset: no branch); two read-write storage
/// textures of one `R32Float` a key (WebGPU allows read-write storage textures of 32-bit
/// single-channel formats only), row textures ([`ROW_TEXELS`] a row) of four texels a segment.
/// llvmpipe moves a storage texture's texels for all the lanes of a SIMD group at once and a
/// storage buffer's words lane by lane: heapsorting 16,384 lists of 128 keys took 260 ms in a
/// buffer and 110 ms in two such textures. In binding order: depths (6), values (7).
const KEY_TEXTURES: [&str; 2] = ["key_depths", "key_values"];
const KEY_BINDINGS: [u32; 2] = [6, 7];
/// The binding of the per-tile texel order (`texel_order` in
/// shaders/shadow/deep_capture_lists.wgsl).
const TEXEL_ORDER_BINDING: u32 = 8;

const SORT_KEY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const SORT_KEY_BYTES: u64 = 4;

/// The resolved nodes (z, Ω(z)) of a resolve into nodes: one `Rgba32Float` row texture, two
/// nodes a texel (nodes 2j and 2j + 1 in texel j: one texel a segment; a 1x1 placeholder for the
/// others), which the resolve's last pass writes (bound write-only) and the owner's pass reads
/// (bound read-only: `resolved_nodes` in shaders/shadow/deep_capture_lists.wgsl). `dsm`'s
/// search loads every node once per greedy fit, and the loads are most of its cost: one load of
/// an `Rg32Float` node took llvmpipe 25 ms where loading its depth and value from the two key
/// textures took 38-46 (300 loads an invocation over a 512² grid), and one `Rgba32Float` load
/// 34-36 ms, for two nodes (search 76 -> 69 ms on the thesis frame with a node a texel, 69 -> 59
/// with two).
const NODES_BINDING: u32 = 9;
const NODE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const NODE_TEXEL_BYTES: u64 = 16;

/// The resolved nodes' texels for lists of `capacity` segments: one a segment (its two nodes)
/// for a resolve into nodes, else one (a placeholder for the binding).
fn resolved_node_count(capacity: u64, node_texels: bool) -> u64 {
    match node_texels {
        true => capacity,
        false => 1,
    }
}

/// The key textures' texels for lists of `capacity` segments: four a segment for a resolve into
/// nodes (two events, each a sort key on either side), else one (a placeholder for the binding).
fn node_texel_count(capacity: u64, node_texels: bool) -> u64 {
    match node_texels {
        true => 4 * capacity,
        false => 1,
    }
}

/// Segments the lists hold before the first frame asks for more (what a technique plans for
/// before its first build).
pub const INITIAL_CAPACITY: u32 = 1 << 16;
/// The colour target the list passes rasterise into, 4 bytes a texel either way: where 32-bit
/// floats blend and a row of it copies into the counts as it is (`counts_by_blending`), the count
/// pass counts there by additive blending (the thesis frame's count pass 12 -> 6.5-7.5 ms, plus
/// 0.7-0.9 for the copy, against atomics) and the fill adds nothing; elsewhere the count pass
/// counts with atomics and the target is a dummy (both passes add nothing to it).
const COUNT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const DUMMY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Whether the count pass of a capture at `resolution_px` counts by blending on `gpu`: 32-bit
/// float targets blend there, and a row of the count target is a whole number of the copy's
/// row alignment (256 bytes: `resolution_px` a multiple of 64), so it copies into the counts
/// as it is.
fn counts_by_blending(gpu: &Gpu, resolution_px: u32) -> bool {
    gpu.features.contains(wgpu::Features::FLOAT32_BLENDABLE)
        && (resolution_px * 4).is_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

/// The bytes a capture at `resolution_px` with lists for `segment_capacity` segments allocates:
/// a 32-byte uniform, the 64 KiB round uniform, counts, offsets (+1 for the total), row sums
/// (+1), the texel order (64 entries a tile of 8x8 texels), a raster target of 4 bytes a texel
/// (`COUNT_FORMAT` or `DUMMY_FORMAT`), 16 bytes of
/// segment storage per segment, and for `avsm` 16 bytes of node storage per segment, for `dsm`
/// (`node_texels`) the two key textures (`KEY_TEXTURES`), 4 x capacity texels of 4 bytes each
/// in whole rows, and the resolved nodes (`NODE_FORMAT`), capacity texels of 16 bytes each in
/// whole rows: 48 bytes a segment (the others' are placeholders).
pub fn bytes(resolution_px: u32, segment_capacity: u64, node_texels: bool) -> u64 {
    let texels = u64::from(resolution_px) * u64::from(resolution_px);
    std::mem::size_of::<CaptureParams>() as u64
        + u64::from(MAX_ROUNDS * ROUND_STRIDE)
        + texels * 4
        + (texels + 1) * 4
        + (u64::from(resolution_px) + 1) * 4
        + texel_order_bytes(resolution_px)
        + texels * 4
        + list_bytes(segment_capacity, node_texels)
}

/// The bytes of the lists sized by the segment capacity ([`Lists`]): the segments, `avsm`'s
/// nodes, `dsm`'s key textures and resolved nodes (placeholders where unused).
fn list_bytes(segment_capacity: u64, node_texels: bool) -> u64 {
    let (width, height) = row_texture_size(node_texel_count(segment_capacity, node_texels));
    let (node_width, node_height) =
        row_texture_size(resolved_node_count(segment_capacity, node_texels));
    segment_buffer_bytes(segment_capacity)
        + node_buffer_bytes(segment_capacity, node_texels)
        + u64::from(width) * u64::from(height) * KEY_TEXTURES.len() as u64 * SORT_KEY_BYTES
        + u64::from(node_width) * u64::from(node_height) * NODE_TEXEL_BYTES
}

/// The most segments lists may hold in `room` bytes (at most `max_segments`, one binding's): a
/// technique under a memory limit captures in bands of what its limit leaves.
fn segments_in(room: u64, node_texels: bool, max_segments: u32) -> u32 {
    crate::gpu::largest_that_fits(0..=max_segments, |c| {
        list_bytes(u64::from(c), node_texels) <= room
    })
    .unwrap_or(0)
}

/// The texel order's bytes at `resolution`: 64 entries of 4 bytes for every 8x8 tile of the map.
fn texel_order_bytes(resolution: u32) -> u64 {
    u64::from(resolution.div_ceil(8)).pow(2) * 64 * 4
}

/// The segments buffer's bytes: [`SEGMENT_BYTES`] a segment of capacity (every fill stores the
/// segments; `dsm`'s run sort splits them into events as it reads them).
fn segment_buffer_bytes(segment_capacity: u64) -> u64 {
    segment_capacity * SEGMENT_BYTES
}

/// The nodes buffer's bytes: [`NODE_BYTES_PER_SEGMENT`] a segment of capacity (`avsm` keeps its
/// curve there between rounds), or for a resolve into nodes, whose nodes are a texture
/// (`NODE_FORMAT`), one segment's, a placeholder for the binding.
fn node_buffer_bytes(segment_capacity: u64, node_texels: bool) -> u64 {
    match node_texels {
        true => NODE_BYTES_PER_SEGMENT,
        false => segment_capacity * NODE_BYTES_PER_SEGMENT,
    }
}

/// The most segments one band may hold: the segments (16 bytes each, and `avsm`'s nodes as
/// many) within one storage binding, and `dsm`'s keys (four texels a segment) within the key
/// textures' rows (its nodes, one texel a segment, fit when they do). Both owners band by both
/// bounds, though `dsm` binds no buffer of nodes: the bands stay the same for both, and so does
/// the test that holds banded maps to whole ones (tests/techniques.rs).
fn max_band_segments(gpu: &Gpu) -> u32 {
    let binding =
        gpu.limits.max_storage_buffer_binding_size / SEGMENT_BYTES.max(NODE_BYTES_PER_SEGMENT);
    let rows = crate::gpu::max_texture_rows(gpu.limits.max_texture_dimension_2d);
    let texture = rows * u64::from(ROW_TEXELS) / node_texel_count(1, true);
    u32::try_from(binding.min(texture)).unwrap_or(u32::MAX)
}

/// Buffers sized by the segment capacity, and the bind group over all the capture's buffers.
struct Lists {
    capacity: u32,
    /// Held with the bind group that uses them (the ledger records their sizes).
    _segments: wgpu::Buffer,
    _nodes: wgpu::Buffer,
    /// The key textures ([`KEY_TEXTURES`]) and the resolved nodes ([`NODE_FORMAT`]) (1x1
    /// placeholders unless the resolve is into nodes), held with the bind groups.
    _keys: [wgpu::Texture; 2],
    _resolved_nodes: wgpu::Texture,
    /// Whether the resolve is into nodes.
    node_texels: bool,
    /// The group of the capture's own passes (the resolved nodes write-only) and of its
    /// owner's (read-only).
    own_bind_group: wgpu::BindGroup,
    bind_group: wgpu::BindGroup,
}

/// The capture's two layouts of group 1: the same bindings, the resolved nodes write-only in
/// its own passes and read-only in its owner's.
struct Layouts {
    capture: wgpu::BindGroupLayout,
    owner: wgpu::BindGroupLayout,
}

/// The capture's pipelines and buffers (see the module doc).
pub struct DeepCapture {
    /// The owning technique's name, the prefix of every label.
    name: &'static str,
    resolution: u32,
    params_buffer: wgpu::Buffer,
    counts: wgpu::Buffer,
    offsets: wgpu::Buffer,
    row_sums: wgpu::Buffer,
    /// Per 8x8 tile of the band, its texels in the order the per-texel passes take them.
    texel_order: wgpu::Buffer,
    /// The raster target, and whether the count pass counts into it (`counts_by_blending`).
    raster_target: wgpu::Texture,
    raster_view: wgpu::TextureView,
    blended_counts: bool,
    layouts: Layouts,
    count_pipeline: wgpu::RenderPipeline,
    fill_pipeline: wgpu::RenderPipeline,
    /// The density volume's count and fill (shaders/shadow/volume_splat.wgsl), and whether
    /// this frame's capture draws them.
    count_volume: VolumeBuild,
    fill_volume: VolumeBuild,
    volume: bool,
    /// The counts from the count target's floats (`counts_by_blending`).
    counts_from_blend: wgpu::ComputePipeline,
    scan_rows: wgpu::ComputePipeline,
    scan_total: wgpu::ComputePipeline,
    scan_write: wgpu::ComputePipeline,
    /// The resolve's phases, in order, each with its kind (which sets its rounds).
    resolve: Vec<(ResolvePhase, wgpu::ComputePipeline)>,
    rounds: Rounds,
    lists: Lists,
    /// Segments stored last frame, in all bands.
    last_segment_count: u64,
    /// Bands last frame was captured in.
    last_band_count: u32,
    /// The longest texel list last frame.
    last_max_list: u32,
    /// Loop iterations a dispatch may run per invocation group on this adapter.
    loop_budget: u32,
}

/// One phase of the resolve (an entry point of shaders/shadow/deep_capture.wgsl).
#[derive(Clone, Copy, Debug)]
enum ResolvePhase {
    /// A heap build (`true`) or extraction over the lists, in rounds.
    Heap(bool),
    /// A single pass, looping up to 2n times (64 for `order_texels`).
    Single,
    /// The merge sort's passes but the last, one a round ([`merge_passes`] - 1).
    Merge,
}

/// What the resolve leaves in the lists for the owner's pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resolve {
    /// Segments' starts and ends sorted by depth into the nodes (z, Ω(z)) of the texel's
    /// optical depth (`dsm`).
    Nodes,
    /// Segments sorted by (z0, z1, optical depth) only (`avsm`'s sorted insertion).
    SegmentsByDepth,
    /// Segments in the order their particles were drawn (`avsm`'s streaming insertion).
    SegmentsByDraw,
}

impl Resolve {
    /// Whether the resolve is into nodes, sorted in the key textures (`KEY_TEXTURES`) and
    /// written to a texture of their own (`NODE_FORMAT`; `node_texel` in
    /// shaders/shadow/dsm_build.wgsl): llvmpipe moves a storage texture's texels for all the
    /// lanes of a SIMD group at once, where it moves a storage buffer's words lane by lane, and
    /// `dsm`'s search reads every node once per greedy fit.
    pub fn node_texels(self) -> bool {
        self == Resolve::Nodes
    }

    /// The phases in order: entry point and kind.
    /// Both begin with `order_texels`, which orders each tile's texels by list length for the
    /// passes after it (`band_texel` in shaders/shadow/deep_capture_lists.wgsl).
    fn phases(self) -> &'static [(&'static str, ResolvePhase)] {
        // Whole segments: an insertion sort that gives up early, then the heapsort for the
        // lists it left.
        const SEGMENTS: [(&str, ResolvePhase); 4] = [
            ("order_texels", ResolvePhase::Single),
            ("insertion_sort", ResolvePhase::Single),
            ("heap_build", ResolvePhase::Heap(true)),
            ("heap_extract", ResolvePhase::Heap(false)),
        ];
        // The run sort splits each segment into its two events as it reads them; every
        // texel's last merge pass, in a dispatch of their own, writes the nodes.
        const NODES: [(&str, ResolvePhase); 4] = [
            ("order_texels", ResolvePhase::Single),
            ("run_sort", ResolvePhase::Single),
            ("merge_runs", ResolvePhase::Merge),
            ("merge_last", ResolvePhase::Single),
        ];
        match self {
            Resolve::Nodes => &NODES,
            Resolve::SegmentsByDepth | Resolve::SegmentsByDraw => &SEGMENTS,
        }
    }
}

/// Bytes between round indices in the round uniform: WebGPU's largest uniform offset alignment,
/// so every adapter accepts it.
const ROUND_STRIDE: u32 = 256;

/// The round indices 0..MAX_ROUNDS, one per `ROUND_STRIDE`, which a per-texel pass binds as
/// its group 3 at a dynamic offset (`Round` in shaders/shadow/deep_capture_lists.wgsl).
pub struct Rounds {
    layout: wgpu::BindGroupLayout,
    /// Held with the bind group (the ledger records its size).
    _buffer: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl Rounds {
    fn new(gpu: &Gpu, memory: &mut MemoryLedger, name: &str) -> Result<Self, AllocationError> {
        let device = &gpu.device;
        let buffer = memory.buffer_transient(
            device,
            &wgpu::BufferDescriptor {
                label: Some(&format!("{name}.capture.rounds")),
                size: u64::from(MAX_ROUNDS * ROUND_STRIDE),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let mut indices = vec![0u32; (MAX_ROUNDS * ROUND_STRIDE / 4) as usize];
        for r in 0..MAX_ROUNDS {
            indices[(r * ROUND_STRIDE / 4) as usize] = r;
        }
        gpu.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(&indices));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&format!("{name}.capture.rounds.layout")),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(4),
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{name}.capture.rounds.bind_group")),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(16),
                }),
            }],
        });
        Ok(Self {
            layout,
            _buffer: buffer,
            bind_group,
        })
    }

    /// Layout of the round group (group 3 of a per-texel pass).
    pub fn layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// Dispatches rounds 0..count of the pass's pipeline over `groups`, each bound to its index.
    /// (No pass needs more than `MAX_ROUNDS`: lists are refused beyond nearly half the loop
    /// budget, where avsm, the pass with the most, takes 100.)
    pub fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>, count: u32, groups: (u32, u32)) {
        debug_assert!(count <= MAX_ROUNDS, "{count} rounds");
        for r in 0..count.min(MAX_ROUNDS) {
            pass.set_bind_group(3, &self.bind_group, &[r * ROUND_STRIDE]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
    }
}

/// What the owner's pass over a band gets: the band, the capture's group (group 1), the round
/// group (group 3), and the frame's longest list and loop budget, from which its rounds follow.
pub struct BandPass<'a> {
    pub band: Band,
    pub capture: &'a wgpu::BindGroup,
    pub rounds: &'a Rounds,
    pub max_list: u32,
    pub loop_budget: u32,
}

/// Rows [row_begin, row_end) of the map, whose segments start at `base` in the frame's offsets
/// and number `segments`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Band {
    pub row_begin: u32,
    pub row_end: u32,
    pub base: u32,
    pub segments: u32,
}

impl Band {
    pub fn rows(&self) -> u32 {
        self.row_end - self.row_begin
    }
}

/// The exclusive prefix sums of the rows' totals of a `side`² grid of counts, then the total
/// (side + 1 entries): what the scan leaves in the row sums.
fn row_offsets(counts: &[u32], side: usize) -> Vec<u32> {
    let mut out = Vec::with_capacity(side + 1);
    let mut running = 0u32;
    out.push(running);
    for row in counts.chunks_exact(side.max(1)).take(side) {
        running = row.iter().fold(running, |sum, &c| sum.wrapping_add(c));
        out.push(running);
    }
    out
}

/// Splits rows into bands of at most `max_segments` segments, given `row_offsets`, the exclusive
/// prefix sums of the rows' segment counts followed by the total (rows + 1 entries). Err(row,
/// its segments) names a row that alone exceeds `max_segments`.
pub fn plan_bands(row_offsets: &[u32], max_segments: u32) -> Result<Vec<Band>, (u32, u32)> {
    let rows = row_offsets.len().saturating_sub(1) as u32;
    let mut bands = Vec::new();
    let mut begin = 0;
    while begin < rows {
        let base = row_offsets[begin as usize];
        let mut end = begin;
        while end < rows && row_offsets[end as usize + 1] - base <= max_segments {
            end += 1;
        }
        if end == begin {
            let row = row_offsets[begin as usize + 1] - base;
            return Err((begin, row));
        }
        bands.push(Band {
            row_begin: begin,
            row_end: end,
            base,
            segments: row_offsets[end as usize] - base,
        });
        begin = end;
    }
    Ok(bands)
}

impl DeepCapture {
    /// Builds the capture for technique `name` at `resolution_px`, recording its buffers in
    /// `memory` as transient. `frame_layout` is group 0 of every pass.
    pub fn new(
        gpu: &Gpu,
        frame_layout: &wgpu::BindGroupLayout,
        name: &'static str,
        resolution_px: u32,
        resolve: Resolve,
        memory: &mut MemoryLedger,
    ) -> Result<Self, ShadowError> {
        let device = &gpu.device;
        let res = resolution_px;
        let texels = u64::from(res) * u64::from(res);
        let label = |what: &str| format!("{name}.capture.{what}");
        let params_buffer = memory.buffer_transient(
            device,
            &wgpu::BufferDescriptor {
                label: Some(&label("params")),
                size: std::mem::size_of::<CaptureParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let mut storage = |what: &str, size: u64| {
            memory.buffer_transient(device, &storage_descriptor(&label(what), size))
        };
        let counts = storage("counts", texels * 4)?;
        let offsets = storage("offsets", (texels + 1) * 4)?;
        let row_sums = storage("row_sums", (u64::from(res) + 1) * 4)?;
        let texel_order = storage("texel_order", texel_order_bytes(res))?;
        let blended_counts = counts_by_blending(gpu, res);
        let raster_format = if blended_counts {
            COUNT_FORMAT
        } else {
            DUMMY_FORMAT
        };
        let raster_target = memory.texture_transient(
            device,
            &crate::gpu::texture_2d_descriptor(
                &label("raster_target"),
                (res, res),
                raster_format,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            ),
        )?;

        let compute = wgpu::ShaderStages::COMPUTE;
        let raster_and_compute = wgpu::ShaderStages::FRAGMENT | compute;
        let key = |binding| {
            storage_texture_entry(
                binding,
                compute,
                wgpu::StorageTextureAccess::ReadWrite,
                SORT_KEY_FORMAT,
            )
        };
        let layout_with = |what: &str, nodes: wgpu::StorageTextureAccess| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(&label(what)),
                entries: &[
                    uniform_entry(0, wgpu::ShaderStages::VERTEX | raster_and_compute),
                    storage_entry(1, raster_and_compute, false),
                    storage_entry(2, raster_and_compute, false),
                    storage_entry(3, raster_and_compute, false),
                    storage_entry(4, compute, false),
                    storage_entry(5, compute, false),
                    key(KEY_BINDINGS[0]),
                    key(KEY_BINDINGS[1]),
                    storage_entry(TEXEL_ORDER_BINDING, compute, false),
                    storage_texture_entry(NODES_BINDING, compute, nodes, NODE_FORMAT),
                ],
            })
        };
        let layouts = Layouts {
            capture: layout_with("layout", wgpu::StorageTextureAccess::WriteOnly),
            owner: layout_with("owner_layout", wgpu::StorageTextureAccess::ReadOnly),
        };
        let layout = &layouts.capture;
        let module = shaders::module(
            device,
            &label("build"),
            &shaders::compose("shadow/deep_capture.wgsl", &[]),
        );
        let groups = [Some(frame_layout), Some(layout)];
        let raster = |what: &str, entry: &str| {
            billboard_pipeline(
                device,
                &label(what),
                &module,
                entry,
                &groups,
                &[raster_format],
                super::layered::ADDITIVE,
            )
        };
        let count_entry = if blended_counts {
            "fs_count_blended"
        } else {
            "fs_count"
        };
        let count_pipeline = raster("count", count_entry);
        let fill_pipeline = raster("fill", "fs_fill");
        let volume = |what: &str, entry: &'static str| {
            VolumeBuild::new(
                device,
                &module,
                label(what),
                entry,
                &[frame_layout, layout],
                &[(raster_format, super::layered::ADDITIVE)],
            )
        };
        let count_volume = volume(
            "count.volume",
            if blended_counts {
                "fs_count_volume_blended"
            } else {
                "fs_count_volume"
            },
        );
        let fill_volume = volume("fill.volume", "fs_fill_volume");
        let compute_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&label("compute.pipeline_layout")),
            bind_group_layouts: &groups,
            immediate_size: 0,
        });
        let rounds = Rounds::new(gpu, memory, name)?;
        let round_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&label("rounds.pipeline_layout")),
            bind_group_layouts: &[
                Some(frame_layout),
                Some(layout),
                None,
                Some(rounds.layout()),
            ],
            immediate_size: 0,
        });
        let pipeline = |entry: &str, layout: &wgpu::PipelineLayout, constants: &[(&str, f64)]| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&label(entry)),
                layout: Some(layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            })
        };
        let compute = |entry: &str| pipeline(entry, &compute_layout, &[]);
        let by_draw = f64::from(u8::from(resolve == Resolve::SegmentsByDraw));
        let node_texels = resolve.node_texels();
        let resolve = resolve
            .phases()
            .iter()
            .map(|&(entry, phase)| {
                let constants = [("SORT_BY_DRAW", by_draw)];
                (phase, pipeline(entry, &round_layout, &constants))
            })
            .collect();
        let lists = Lists::new(
            device,
            memory,
            name,
            &layouts,
            [&params_buffer, &counts, &offsets, &row_sums, &texel_order],
            // Within what a memory limit leaves (at least one segment: a limit below that is
            // the ledger's one line).
            segments_in(
                memory.remaining_bytes(),
                node_texels,
                INITIAL_CAPACITY.min(max_band_segments(gpu)),
            )
            .max(1),
            node_texels,
        )?;
        let capture = Self {
            name,
            resolution: res,
            counts_from_blend: compute("counts_from_blend"),
            scan_rows: compute("scan_rows"),
            scan_total: compute("scan_total"),
            scan_write: compute("scan_write"),
            resolve,
            rounds,
            params_buffer,
            counts,
            offsets,
            row_sums,
            texel_order,
            raster_view: raster_target.create_view(&wgpu::TextureViewDescriptor::default()),
            raster_target,
            blended_counts,
            layouts,
            count_pipeline,
            fill_pipeline,
            count_volume,
            fill_volume,
            volume: false,
            lists,
            last_segment_count: 0,
            last_band_count: 0,
            last_max_list: 0,
            loop_budget: gpu.loop_budget().unwrap_or(UNBOUNDED_LOOP_BUDGET),
        };
        Ok(capture)
    }

    /// Layout of the capture's group as a compression pass binds it (its group 1: the
    /// resolved nodes read-only).
    pub fn layout(&self) -> &wgpu::BindGroupLayout {
        &self.layouts.owner
    }

    /// Layout of the round group (group 3 of a compression pass).
    pub fn rounds_layout(&self) -> &wgpu::BindGroupLayout {
        self.rounds.layout()
    }

    /// This frame's group over the lists as a compression pass binds it (replaced when they
    /// grow: take it after [`DeepCapture::record`]).
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.lists.bind_group
    }

    /// Segments stored last frame, in all bands.
    pub fn segments(&self) -> u64 {
        self.last_segment_count
    }

    /// Bands last frame was captured in (1 when its segments fit one binding).
    pub fn bands(&self) -> u32 {
        self.last_band_count
    }

    /// The longest texel list last frame.
    pub fn max_list(&self) -> u32 {
        self.last_max_list
    }

    /// Segments the lists hold.
    pub fn capacity(&self) -> u32 {
        self.lists.capacity
    }

    /// Whether the count pass counts by blending (`counts_by_blending`), else with atomics.
    pub fn counts_by_blending(&self) -> bool {
        self.blended_counts
    }

    /// Points the passes at `band` (landing at the next submission).
    fn write_params(&self, queue: &wgpu::Queue, band: Band) {
        queue.write_buffer(
            &self.params_buffer,
            0,
            bytemuck::bytes_of(&CaptureParams {
                resolution: self.resolution,
                capacity: self.lists.capacity,
                row_begin: band.row_begin,
                row_end: band.row_end,
                band_base: band.base,
                max_list: self.last_max_list,
                loop_budget: self.loop_budget,
                _pad: 0,
            }),
        );
    }

    /// The whole map as one band (for the count and scan, which cover every texel).
    fn whole_map(&self) -> Band {
        Band {
            row_begin: 0,
            row_end: self.resolution,
            base: 0,
            segments: 0,
        }
    }

    /// Captures this frame: counts and scans in a submission of its own, reads the rows' offsets
    /// back, plans the bands (see the module doc) and grows the lists (recorded in `memory`) when
    /// they cannot hold the largest, then per band records the fill, the resolve and
    /// `after_band` (the owner's pass over the band: it must cover the band's rows only, as
    /// `band_texel` in shaders/shadow/deep_capture_lists.wgsl does, with the bind group it is
    /// given as group 1). The last band goes into `encoder`, the others are submitted.
    #[allow(clippy::too_many_arguments)]
    pub async fn record(
        &mut self,
        gpu: &Gpu,
        memory: &mut MemoryLedger,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
        volume: bool,
        mut after_band: impl FnMut(&mut wgpu::CommandEncoder, &mut GpuTimer, &BandPass<'_>),
    ) -> Result<(), ShadowError> {
        let device = &gpu.device;
        // The scene's density volume's segments join the particles' (each step of a texel's
        // light ray with density, `volume.build_steps` of them at most).
        self.volume = volume;
        self.write_params(&gpu.queue, self.whole_map());
        let mut count_encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some(&format!("{}.capture.count.encoder", self.name)),
        });
        count_encoder.clear_buffer(&self.counts, 0, None);
        self.raster(
            &mut count_encoder,
            timer,
            None,
            frame_bind_group,
            particles,
            particle_count,
        );
        if self.blended_counts {
            self.take_blended_counts(&mut count_encoder, timer, frame_bind_group);
        }
        // Each scan step in a pass of its own, so that each sees the previous one's writes
        // whatever the backend's barriers between dispatches of one pass.
        let row_groups = self.resolution.div_ceil(64);
        for (pipeline, groups) in [
            (&self.scan_rows, row_groups),
            (&self.scan_total, 1),
            (&self.scan_write, row_groups),
        ] {
            let mut pass = count_encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(&format!("{}.capture.scan", self.name)),
                timestamp_writes: timer.compute_pass("shadow"),
            });
            pass.set_bind_group(0, frame_bind_group, &[]);
            pass.set_bind_group(1, &self.lists.own_bind_group, &[]);
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        gpu.queue.submit([count_encoder.finish()]);
        // One readback: the counts give the longest list and, summed per row, the rows'
        // offsets (the same u32 sums the scan wrote on the GPU).
        let texels = u64::from(self.resolution).pow(2);
        let counts: Vec<u32> = read_buffer(gpu, &self.counts, 0, texels * 4)
            .await
            .map_err(|err| ShadowError::Gpu(err.to_string()))?
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        self.last_max_list = counts.iter().copied().max().unwrap_or(0);
        let row_offsets = row_offsets(&counts, self.resolution as usize);
        let longest_allowed = longest_list(self.loop_budget);
        if self.last_max_list > longest_allowed {
            return Err(ShadowError::TexelListTooLong {
                technique: self.name,
                resolution_px: self.resolution,
                longest: self.last_max_list,
                limit: longest_allowed,
            });
        }
        // Bands of what one binding holds, and what the memory limit leaves for the lists
        // (the ledger's remaining bytes and the lists' own, which they would give up).
        let node_texels = self.lists.node_texels;
        let room =
            memory.remaining_bytes() + list_bytes(u64::from(self.lists.capacity), node_texels);
        let max_segments = segments_in(room, node_texels, max_band_segments(gpu));
        let bands = plan_bands(&row_offsets, max_segments).map_err(|(row, segments)| {
            ShadowError::CaptureTooLarge {
                technique: self.name,
                resolution_px: self.resolution,
                row,
                segments: u64::from(segments),
                limit: u64::from(max_segments),
            }
        })?;
        let largest = bands.iter().map(|b| b.segments).max().unwrap_or(0);
        if largest > self.lists.capacity {
            self.grow(gpu, memory, largest, max_segments)?;
        }
        self.last_segment_count = u64::from(row_offsets[self.resolution as usize]);
        self.last_band_count = bands.len() as u32;

        // Per band: fill (counts, cleared, become the cursors), sort and resolve, then the
        // owner's pass.
        let last = bands.len().saturating_sub(1);
        for (i, &band) in bands.iter().enumerate() {
            self.write_params(&gpu.queue, band);
            let mut own = (i < last).then(|| {
                device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some(&format!("{}.capture.band.encoder", self.name)),
                })
            });
            let band_encoder = own.as_mut().unwrap_or(&mut *encoder);
            self.record_band(
                band_encoder,
                timer,
                band,
                frame_bind_group,
                particles,
                particle_count,
            );
            let band_pass = BandPass {
                band,
                capture: &self.lists.bind_group,
                rounds: &self.rounds,
                max_list: self.last_max_list,
                loop_budget: self.loop_budget,
            };
            after_band(band_encoder, timer, &band_pass);
            if let Some(own) = own {
                gpu.queue.submit([own.finish()]);
            }
        }
        Ok(())
    }

    /// Records the copy of the count pass's blended counts into `counts` (a float's bits a
    /// texel) and their conversion there to integers.
    fn take_blended_counts(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
    ) {
        let side = self.resolution;
        encoder.copy_texture_to_buffer(
            self.raster_target.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.counts,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(side * 4),
                    rows_per_image: Some(side),
                },
            },
            wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: 1,
            },
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(&format!("{}.capture.counts_from_blend", self.name)),
            timestamp_writes: timer.compute_pass("shadow"),
        });
        pass.set_pipeline(&self.counts_from_blend);
        pass.set_bind_group(0, frame_bind_group, &[]);
        pass.set_bind_group(1, &self.lists.own_bind_group, &[]);
        pass.dispatch_workgroups(side.div_ceil(8), side.div_ceil(8), 1);
    }

    /// Records one band's fill and resolve.
    fn record_band(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        band: Band,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
    ) {
        encoder.clear_buffer(&self.counts, 0, None);
        self.raster(
            encoder,
            timer,
            Some(band),
            frame_bind_group,
            particles,
            particle_count,
        );
        let (build_rounds, extract_rounds) = heap_rounds(self.last_max_list, self.loop_budget);
        let groups = (self.resolution.div_ceil(8), band.rows().div_ceil(8));
        for (phase, pipeline) in &self.resolve {
            let rounds = match phase {
                ResolvePhase::Heap(true) => build_rounds,
                ResolvePhase::Heap(false) => extract_rounds,
                ResolvePhase::Single => 1,
                ResolvePhase::Merge => merge_passes(self.last_max_list).saturating_sub(1),
            };
            if rounds == 0 {
                continue;
            }
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(&format!("{}.capture.resolve", self.name)),
                timestamp_writes: timer.compute_pass("shadow"),
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, frame_bind_group, &[]);
            pass.set_bind_group(1, &self.lists.own_bind_group, &[]);
            self.rounds.dispatch(&mut pass, rounds, groups);
        }
    }

    /// Reallocates the lists for at least `total` segments, with headroom so that a slowly
    /// changing scene does not reallocate every frame.
    /// (`total` is at most `max_segments`, the most one binding holds.)
    fn grow(
        &mut self,
        gpu: &Gpu,
        memory: &mut MemoryLedger,
        total: u32,
        max_segments: u32,
    ) -> Result<(), ShadowError> {
        let capacity = total
            .saturating_add(total / 4)
            .max(INITIAL_CAPACITY)
            .min(max_segments.max(total));
        // The ledger forgets the old lists before the new ones are checked against the budget.
        let fixed = [
            &self.params_buffer,
            &self.counts,
            &self.offsets,
            &self.row_sums,
            &self.texel_order,
        ];
        self.lists = Lists::new(
            &gpu.device,
            memory,
            self.name,
            &self.layouts,
            fixed,
            capacity,
            self.lists.node_texels,
        )?;
        Ok(())
    }

    /// Records one raster pass of the light-space particles: the count pass over the whole map,
    /// or the fill pass of one band (scissored to its rows).
    fn raster(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        fill: Option<Band>,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
    ) {
        let (what, pipeline, volume) = match fill {
            Some(_) => ("fill", &self.fill_pipeline, &self.fill_volume),
            None => ("count", &self.count_pipeline, &self.count_volume),
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(&format!("{}.capture.{what}", self.name)),
            color_attachments: &[cleared_attachment(
                &self.raster_view,
                wgpu::Color::TRANSPARENT,
            )],
            depth_stencil_attachment: None,
            timestamp_writes: timer.pass("shadow"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some(band) = fill {
            pass.set_scissor_rect(0, band.row_begin, self.resolution, band.rows());
        }
        draw_particles(
            &mut pass,
            pipeline,
            frame_bind_group,
            &self.lists.own_bind_group,
            particles.slice(..),
            particle_count,
        );
        if self.volume {
            volume.draw(&mut pass, frame_bind_group, &self.lists.own_bind_group);
        }
    }
}

impl Lists {
    /// Allocates (transient) list buffers for `capacity` segments (placeholders when
    /// `node_texels`), the key textures and the resolved nodes (room for the keys and nodes
    /// when `node_texels`, else 1x1), and the two bind groups (`layouts`) over them and the
    /// fixed buffers `[params, counts, offsets, row_sums, texel_order]`.
    fn new(
        device: &wgpu::Device,
        memory: &mut MemoryLedger,
        name: &str,
        layouts: &Layouts,
        fixed: [&wgpu::Buffer; 5],
        capacity: u32,
        node_texels: bool,
    ) -> Result<Self, AllocationError> {
        let [params, counts, offsets, row_sums, texel_order] = fixed;
        let (segments_label, nodes_label) = (
            format!("{name}.capture.segments"),
            format!("{name}.capture.nodes"),
        );
        let key_labels = KEY_TEXTURES.map(|what| format!("{name}.capture.{what}"));
        let resolved_label = format!("{name}.capture.resolved_nodes");
        memory.forget(&segments_label);
        memory.forget(&nodes_label);
        for label in key_labels.iter().chain([&resolved_label]) {
            memory.forget(label);
        }
        let segments = memory.buffer_transient(
            device,
            &storage_descriptor(&segments_label, segment_buffer_bytes(u64::from(capacity))),
        )?;
        let nodes = memory.buffer_transient(
            device,
            &storage_descriptor(
                &nodes_label,
                node_buffer_bytes(u64::from(capacity), node_texels),
            ),
        )?;
        let mut keys = Vec::with_capacity(KEY_TEXTURES.len());
        for label in &key_labels {
            keys.push(memory.texture_transient(
                device,
                &row_texture_descriptor(
                    label,
                    SORT_KEY_FORMAT,
                    wgpu::TextureUsages::STORAGE_BINDING,
                    node_texel_count(u64::from(capacity), node_texels),
                ),
            )?);
        }
        let keys: [wgpu::Texture; 2] = keys.try_into().expect("two key textures");
        let resolved_nodes = memory.texture_transient(
            device,
            &row_texture_descriptor(
                &resolved_label,
                NODE_FORMAT,
                wgpu::TextureUsages::STORAGE_BINDING,
                resolved_node_count(u64::from(capacity), node_texels),
            ),
        )?;
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let key_views = keys.each_ref().map(view);
        let resolved_view = view(&resolved_nodes);
        let bind_group_with = |what: &str, layout: &wgpu::BindGroupLayout| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(&format!("{name}.capture.{what}")),
                layout,
                entries: &[
                    bind_entry(0, params),
                    bind_entry(1, counts),
                    bind_entry(2, offsets),
                    bind_entry(3, &segments),
                    bind_entry(4, &nodes),
                    bind_entry(5, row_sums),
                    texture_binding(KEY_BINDINGS[0], &key_views[0]),
                    texture_binding(KEY_BINDINGS[1], &key_views[1]),
                    bind_entry(TEXEL_ORDER_BINDING, texel_order),
                    texture_binding(NODES_BINDING, &resolved_view),
                ],
            })
        };
        Ok(Self {
            capacity,
            own_bind_group: bind_group_with("bind_group", &layouts.capture),
            bind_group: bind_group_with("owner_bind_group", &layouts.owner),
            _segments: segments,
            _nodes: nodes,
            _keys: keys,
            _resolved_nodes: resolved_nodes,
            node_texels,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Offsets from per-row counts (exclusive prefix sums, then the total).
    fn offsets(counts: &[u32]) -> Vec<u32> {
        let mut out = vec![0];
        for c in counts {
            out.push(out.last().unwrap() + c);
        }
        out
    }

    #[test]
    fn merge_passes_are_enough_and_never_fewer_for_a_longer_list() {
        let mut before = 0;
        for n in 0..20_000u32 {
            let passes = merge_passes(n);
            // The 2n events in runs of RUN; eight runs merged a pass (WAY_LEVELS levels), the
            // last pass the levels left over.
            let runs = (2 * n).div_ceil(RUN);
            let levels = if runs <= 1 { 0 } else { (runs - 1).ilog2() + 1 };
            let last = levels - WAY_LEVELS * (passes.max(1) - 1);
            assert!((1..=WAY_LEVELS).contains(&last) || passes == 0, "n {n}");
            let merged_levels = (1..=passes)
                .map(|p| if p == passes { last } else { WAY_LEVELS })
                .sum::<u32>();
            assert!(
                u64::from(RUN) << merged_levels >= 2 * u64::from(n),
                "n {n}: {passes} passes"
            );
            // And no pass more than that needs: one pass fewer would leave two runs at least.
            assert!(
                passes == 0 || u64::from(RUN) << (merged_levels - last) < 2 * u64::from(n),
                "n {n}: {passes} passes"
            );
            assert!(passes >= before, "n {n}");
            before = passes;
        }
        assert_eq!(merge_passes(8), 0);
        assert_eq!(merge_passes(9), 1);
        assert_eq!(merge_passes(64), 1);
        assert_eq!(merge_passes(65), 2);
        assert_eq!(merge_passes(450), 2);
        assert_eq!(merge_passes(512), 2);
        assert_eq!(merge_passes(513), 3);
    }

    #[test]
    fn the_longest_list_sorts_within_the_loop_budget() {
        for budget in [60_000u32, 65_535, 1 << 30] {
            let n = u64::from(longest_list(budget));
            let loops = |n: u64| 2 * n + (2 * n).div_ceil(u64::from(RUN));
            assert!(loops(n) <= u64::from(budget), "budget {budget}: {n}");
            // A list two longer would not fit (the limit is not needlessly low).
            assert!(loops(n + 2) > u64::from(budget), "budget {budget}: {n}");
        }
        assert_eq!(longest_list(60_000), 28_234);
    }

    /// The widths (events) of the groups a list of `events` merges in merge dispatch `dispatch`
    /// (1-based) of `dispatches`, as shaders/shadow/deep_capture.wgsl walks them: every pass
    /// of the list but its last in the dispatch of its index (`merge_runs`), its last (or for a
    /// list of one run, a first) in the last dispatch (`merge_last`); a pass's groups are
    /// `run_width` times `runs_merged` wide, the last group cut at the list's end. None in a
    /// dispatch without a pass of the list.
    fn merge_groups(events: u32, dispatch: u32, dispatches: u32) -> Vec<u32> {
        let passes = merge_passes(events / 2);
        let step = match dispatch == dispatches {
            // A list of one run is copied into its nodes as if by a first pass.
            true if events > 0 => passes.max(1),
            false if dispatch < passes => dispatch,
            _ => 0,
        };
        if step == 0 {
            return Vec::new();
        }
        let last = merge_levels(events) - WAY_LEVELS * (passes.max(1) - 1);
        let width = RUN << (WAY_LEVELS * (step - 1));
        let ways = 1 << if step == passes { last } else { WAY_LEVELS };
        let group = ways * width;
        (0..events.div_ceil(group))
            .map(|g| group.min(events - g * group))
            .collect()
    }

    #[test]
    fn a_merge_pass_loops_for_a_simd_group_no_more_than_for_its_longest_list() {
        // llvmpipe counts loop iterations per SIMD group of invocations, all lanes together: a
        // loop whose lanes have different trip counts runs max(lanes) times, and a loop inside
        // it max(lanes) times at each outer iteration. So the group's count of a merge pass is
        // the sum over group indices g of 1 + the widest lane's group g (plus the outer loop's
        // exit). Every lane's pass `step` must cut its list at the same indices for that to be
        // the longest list's own count: taken here over every list length up to the longest a
        // capture accepts, lanes of any lengths at once (a real group has 4 or 8 lanes; the
        // bound holds for any number).
        let budget = 60_000;
        let longest = longest_list(budget);
        let dispatches = merge_passes(longest);
        for step in 1..=dispatches {
            let mut widest: Vec<u32> = Vec::new();
            for n in 1..=longest {
                let groups = merge_groups(2 * n, step, dispatches);
                for (g, width) in groups.into_iter().enumerate() {
                    if g == widest.len() {
                        widest.push(width);
                    }
                    widest[g] = widest[g].max(width);
                }
            }
            let group_loops: u64 = widest.iter().map(|&w| 1 + u64::from(w)).sum::<u64>() + 1;
            let own: Vec<u32> = merge_groups(2 * longest, step, dispatches);
            let longest_loops = own.iter().map(|&w| 1 + u64::from(w)).sum::<u64>() + 1;
            assert_eq!(group_loops, longest_loops, "step {step}");
            let events = 2 * u64::from(longest);
            assert!(
                group_loops <= events + events.div_ceil(u64::from(RUN)),
                "step {step}: {group_loops}"
            );
            assert!(
                group_loops <= u64::from(budget),
                "step {step}: {group_loops}"
            );
        }
    }

    /// `insertion_sort`'s flat loop (shaders/shadow/deep_capture.wgsl) over `keys` from `start`
    /// (the prefix found in order), iteration for iteration: whether it sorted the list, and
    /// how many times it looped (the exit's iteration included).
    fn flat_insertion_sort(keys: &mut [u32], start: usize) -> (bool, u64) {
        let n = keys.len();
        let mut moves = (n / 16).max(1) - 1;
        let mut loops = 0;
        if n <= start {
            return (true, 1);
        }
        let mut last = keys[start - 1];
        let (mut i, mut j, mut v, mut inserting) = (start, start, last, false);
        loop {
            loops += 1;
            if i >= n {
                return (true, loops);
            }
            if !inserting {
                v = keys[i];
                if v >= last {
                    last = v;
                    i += 1;
                    continue;
                }
                inserting = true;
                j = i;
            }
            let set_down = j == 0 || v >= keys[j - 1];
            if !set_down {
                if moves == 0 {
                    keys[j] = v;
                    return (false, loops);
                }
                keys[j] = keys[j - 1];
                j -= 1;
                moves -= 1;
            } else {
                keys[j] = v;
                inserting = false;
                i += 1;
            }
        }
    }

    #[test]
    fn the_insertion_sort_loops_within_its_bound_on_any_list() {
        // A SIMD group loops the flat loop as often as its busiest lane, and the prefix before
        // it as often as its longest prefix: n + 1 and (n - start) + 2 (n/16 - 1) + 1 at most,
        // whose sum stays within the bound `longest_list` holds every pass to.
        let mut state = 0x9e37_79b9_u32;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        for n in [1usize, 2, 15, 16, 17, 100, 1000, 5000] {
            let sorted: Vec<u32> = (0..n as u32).collect();
            let mut nearly = sorted.clone();
            for k in (0..n).step_by(37) {
                nearly.swap(k, (k + 5).min(n - 1));
            }
            let shuffled: Vec<u32> = sorted.iter().map(|_| random() % 64).collect();
            let reversed: Vec<u32> = sorted.iter().rev().copied().collect();
            for list in [&sorted, &nearly, &shuffled, &reversed] {
                for start in [1, n / 2, n].into_iter().filter(|&s| s >= 1 && s <= n) {
                    let mut keys = list.clone();
                    keys[..start].sort_unstable();
                    let before = keys.clone();
                    let (done, loops) = flat_insertion_sort(&mut keys, start);
                    let moves = ((n / 16).max(1) - 1) as u64;
                    assert!(
                        loops <= (n - start) as u64 + 2 * moves + 1,
                        "n {n}: {loops}"
                    );
                    let mut expected = before.clone();
                    expected.sort_unstable();
                    let mut permutation = keys.clone();
                    permutation.sort_unstable();
                    assert_eq!(permutation, expected, "n {n}: not a permutation");
                    if done {
                        assert_eq!(keys, expected, "n {n}: marked sorted");
                    }
                }
            }
            // (Shorter lists are far within any budget.)
            let n = n as u64;
            let group = (n + 1) + n + 2 * ((n / 16).max(1) - 1) + 1;
            assert!(
                n < 16 || group <= 2 * n + (2 * n).div_ceil(u64::from(RUN)),
                "n {n}"
            );
        }
        // In order, the sort takes each segment once; at the longest list, within the budget.
        let mut keys: Vec<u32> = (0..1000).collect();
        assert_eq!(flat_insertion_sort(&mut keys, 1), (true, 1000));
        let n = u64::from(longest_list(60_000));
        let group = 2 * n + 2 * (n / 16 - 1) + 2;
        assert!(group <= 60_000, "{group}");
    }

    #[test]
    fn bands_cover_every_row_once_and_each_fits() {
        let counts = [3, 0, 5, 2, 2, 7, 0, 0, 1, 4];
        let row_offsets = offsets(&counts);
        for max in [7, 8, 10, 30, 100] {
            let bands = plan_bands(&row_offsets, max).unwrap();
            let mut next = 0;
            for band in &bands {
                assert_eq!(band.row_begin, next, "{max}: {bands:?}");
                assert!(band.row_end > band.row_begin);
                let sum: u32 = counts[band.row_begin as usize..band.row_end as usize]
                    .iter()
                    .sum();
                assert_eq!(band.segments, sum);
                assert_eq!(band.base, row_offsets[band.row_begin as usize]);
                assert!(band.segments <= max, "{max}: {bands:?}");
                next = band.row_end;
            }
            assert_eq!(next, counts.len() as u32);
            // Greedy: no band could have taken the next row as well.
            for pair in bands.windows(2) {
                let next_row = counts[pair[0].row_end as usize];
                assert!(pair[0].segments + next_row > max, "{max}: {bands:?}");
            }
        }
        assert_eq!(plan_bands(&row_offsets, 100).unwrap().len(), 1);
    }

    #[test]
    fn row_offsets_sum_each_row_of_the_grid() {
        let grid = [1, 2, 0, 0, 0, 0, 5, 0, 3];
        assert_eq!(row_offsets(&grid, 3), vec![0, 3, 3, 11]);
    }

    #[test]
    fn a_row_beyond_the_limit_is_named() {
        let row_offsets = offsets(&[3, 9, 1]);
        assert_eq!(plan_bands(&row_offsets, 8), Err((1, 9)));
        // A map with no smoke is one band.
        let empty = offsets(&[0, 0]);
        let bands = plan_bands(&empty, 1).unwrap();
        assert_eq!(bands.len(), 1);
        assert_eq!(bands[0].segments, 0);
    }
}
