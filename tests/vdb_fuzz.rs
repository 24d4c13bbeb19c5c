//! Deterministic fuzzing of the reader: truncations, bit flips, byte overwrites and huge values
//! written over 4- and 8-byte fields of the real files and of synthesized ones. Every call must
//! return Ok or Err: a panic is reported naming the mutant, and a counting allocator checks that
//! no call allocates more than the limits allow.

#[path = "common/vdb_writer.rs"]
mod vdb_writer;

use smokeshadow::medium::vdb::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::time::Instant;
use vdb_writer::*;

/// Counts live bytes, their peak, and the largest single request.
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LARGEST: AtomicUsize = AtomicUsize::new(0);

fn note_alloc(size: usize) {
    let live = LIVE.fetch_add(size, Relaxed) + size;
    PEAK.fetch_max(live, Relaxed);
    LARGEST.fetch_max(size, Relaxed);
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_alloc(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_sub(layout.size(), Relaxed);
        note_alloc(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// xorshift64* (Vigna): small, seeded, good enough to pick offsets and values.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Offsets of descriptor `end_pos` fields: OpenVDB writes grid_pos, block_pos, end_pos and the
/// grid starts right after them, so an i64 equal to its own offset + 24 marks grid_pos.
fn end_pos_fields(bytes: &[u8]) -> Vec<usize> {
    (0..bytes.len().saturating_sub(24))
        .filter(|&q| i64::from_le_bytes(bytes[q..q + 8].try_into().unwrap()) == q as i64 + 24)
        .map(|q| q + 16)
        .collect()
}

struct Input {
    label: String,
    bytes: Vec<u8>,
    grids: Vec<String>,
}

fn inputs() -> Vec<Input> {
    let mut v: Vec<Input> = REAL_FILES
        .iter()
        .map(|f| {
            let bytes = real_file(f);
            let grids = list_grids(&bytes)
                .unwrap()
                .into_iter()
                .map(|i| i.name)
                .collect();
            Input {
                label: f.to_string(),
                bytes,
                grids,
            }
        })
        .collect();
    // Synthesized: zip + mask compression (every metadata byte), uncompressed half floats with
    // tiles, and blosc with zlib, small blocks and memcpy-free splits.
    let mut zip = Grid::float("zip");
    zip.compression = ZIP | ACTIVE_MASK;
    zip.background = 2.0;
    zip.leaves = (0..7)
        .map(|i| {
            leaf(
                [8 * i, 0, 0],
                |n| n % 3 == 0,
                move |n| {
                    if n % 3 == 0 {
                        n as f32
                    } else {
                        [2.0, -2.0, 7.0, 9.0][(n + i as usize) % 4]
                    }
                },
            )
        })
        .collect();
    let mut half = Grid::float("half");
    half.compression = 0;
    half.half = true;
    half.leaves = vec![leaf([0, 0, 0], |n| n % 2 == 0, |n| n as f32 * 0.5)];
    half.tiles4 = vec![Tile {
        origin: [8, 0, 0],
        value: 3.0,
        active: true,
    }];
    half.tiles5 = vec![Tile {
        origin: [128, 0, 0],
        value: 1.0,
        active: false,
    }];
    let mut blosc = Grid::float("blosc");
    blosc.blosc = BloscOpts {
        codec: Codec::Zlib,
        blocksize: 600,
        ..Default::default()
    };
    blosc.leaves = vec![leaf([0, 0, 0], |n| n % 4 != 0, |n| (n % 13) as f32)];
    for g in [zip, half, blosc] {
        let bytes = write_file(std::slice::from_ref(&g), &mut Stats::default());
        v.push(Input {
            label: format!("synth-{}", g.name),
            bytes,
            grids: vec![g.name.clone()],
        });
    }
    v
}

enum Mutation {
    Truncate(usize),
    /// Truncate and move every descriptor end offset in front of the cut, so that the reader
    /// gets past the descriptors and runs out of bytes inside the tree.
    TruncateDeep(usize),
    FlipBit(usize, u8),
    SetByte(usize, u8),
    Field4(usize, u32),
    Field8(usize, u64),
}

const HUGE4: [u32; 6] = [
    0xFFFF_FFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    (-2i32) as u32,
    0x0010_0000,
    0,
];
const HUGE8: [u64; 6] = [
    u64::MAX,
    i64::MAX as u64,
    i64::MIN as u64,
    (-4096i64) as u64,
    1 << 40,
    0,
];

fn apply(bytes: &[u8], m: &Mutation, end_fields: &[usize]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    match *m {
        Mutation::Truncate(len) => b.truncate(len),
        Mutation::TruncateDeep(len) => {
            for &f in end_fields.iter().filter(|&&f| f + 8 <= len) {
                b[f..f + 8].copy_from_slice(&(len as i64).to_le_bytes());
            }
            b.truncate(len);
        }
        Mutation::FlipBit(at, bit) => b[at] ^= 1 << bit,
        Mutation::SetByte(at, v) => b[at] = v,
        Mutation::Field4(at, v) => b[at..at + 4].copy_from_slice(&v.to_le_bytes()),
        Mutation::Field8(at, v) => b[at..at + 8].copy_from_slice(&v.to_le_bytes()),
    }
    b
}

fn mutations(len: usize, rng: &mut Rng) -> Vec<Mutation> {
    let mut m = Vec::new();
    // Most random mutants of a large file still parse all of it; fewer keep the test quick.
    let scale = if len > 100_000 { 2 } else { 1 };
    let header = len.min(768); // magic, versions, UUID, metadata, descriptors, grid header
    m.extend((0..=header).map(Mutation::Truncate));
    for i in 0..200 {
        let cut = header + (len - header) * i / 200;
        m.push(Mutation::Truncate(cut));
        m.push(Mutation::TruncateDeep(cut));
    }
    for _ in 0..700 / scale {
        m.push(Mutation::FlipBit(rng.below(len), rng.below(8) as u8));
    }
    for _ in 0..300 / scale {
        m.push(Mutation::SetByte(rng.below(len), rng.next() as u8));
    }
    // Huge values over every 4-byte field of the header region and random ones beyond.
    for at in (0..header.saturating_sub(4)).step_by(2) {
        m.push(Mutation::Field4(at, HUGE4[rng.below(HUGE4.len())]));
    }
    for _ in 0..300 / scale {
        let at = rng.below(len - 8);
        m.push(Mutation::Field4(at, HUGE4[rng.below(HUGE4.len())]));
        m.push(Mutation::Field8(at, HUGE8[rng.below(HUGE8.len())]));
    }
    m
}

#[test]
fn fuzzed_files_never_panic_and_stay_within_limits() {
    let start = Instant::now();
    let limits = Limits {
        max_dense_voxels: 1 << 21,
    };
    let inputs = inputs();
    let quiet = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut failures = Vec::new();
    let (mut total, mut errors, mut worst_peak, mut worst_single) =
        (0usize, 0usize, 0usize, 0usize);
    // Mutants with at least one refused read.
    let mut refused = 0usize;
    for (index, input) in inputs.iter().enumerate() {
        let seed = 0x9E37_79B9_7F4A_7C15u64 ^ index as u64;
        let mut rng = Rng(seed);
        let end_fields = end_pos_fields(&input.bytes);
        // Dense grid, scratch buffers, and a topology proportional to the file.
        let bound = 4 * limits.max_dense_voxels as usize + 8 * input.bytes.len() + (1 << 20);
        let input_start = Instant::now();
        let input_total = total;
        for (k, m) in mutations(input.bytes.len(), &mut rng).iter().enumerate() {
            let mutant = apply(&input.bytes, m, &end_fields);
            let what = match m {
                Mutation::Truncate(n) => format!("truncate to {n}"),
                Mutation::TruncateDeep(n) => format!("truncate to {n} with end offsets moved"),
                Mutation::FlipBit(at, b) => format!("flip bit {b} at offset {at}"),
                Mutation::SetByte(at, v) => format!("byte {v:#04x} at offset {at}"),
                Mutation::Field4(at, v) => format!("u32 {v:#x} at offset {at}"),
                Mutation::Field8(at, v) => format!("u64 {v:#x} at offset {at}"),
            };
            let base = LIVE.load(Relaxed);
            PEAK.store(base, Relaxed);
            LARGEST.store(0, Relaxed);
            let outcome = catch_unwind(AssertUnwindSafe(|| {
                let mut errs = usize::from(list_grids(&mutant).is_err());
                for name in &input.grids {
                    errs += usize::from(read_float_grid(&mutant, name, &limits).is_err());
                }
                errs
            }));
            total += 1;
            let peak = PEAK.load(Relaxed).saturating_sub(base);
            let single = LARGEST.load(Relaxed);
            worst_peak = worst_peak.max(peak);
            worst_single = worst_single.max(single);
            match outcome {
                Ok(n) => {
                    errors += n;
                    refused += usize::from(n > 0);
                }
                Err(p) => {
                    let msg = p
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()));
                    failures.push(format!(
                        "{} seed {seed:#x} mutant {k} ({what}): panic {msg:?}",
                        input.label
                    ));
                }
            }
            if peak > bound {
                failures.push(format!(
                    "{} seed {seed:#x} mutant {k} ({what}): peak {peak} bytes > {bound}",
                    input.label
                ));
            }
        }
        let secs = input_start.elapsed().as_secs_f64();
        println!(
            "{}: {} mutants in {secs:.1} s",
            input.label,
            total - input_total
        );
    }
    std::panic::set_hook(quiet);
    println!(
        "{total} mutants of {} inputs, {errors} Err results, worst peak {worst_peak} bytes, largest allocation {worst_single} bytes, {:.1} s",
        inputs.len(),
        start.elapsed().as_secs_f64()
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The mutants reach past the header: some still read, some are refused.
    assert!(
        refused > 0 && refused < total,
        "{refused} of {total} mutants refused"
    );
}
