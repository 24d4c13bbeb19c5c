//! A tiny OpenVDB writer for tests: it writes float grids the way OpenVDB's Archive::write does
//! (header, descriptors with offsets, per-grid compression, metadata, transform, topology, leaf
//! buffers, MaskCompress metadata bytes, zip and blosc chunks), so that the reader's branches
//! the real files do not exercise (no compression, zip, half floats, tiles, every metadata-byte
//! mode, blosc variants) can be tested against known values.
#![allow(dead_code, clippy::needless_range_loop)]

use std::collections::BTreeMap;
use std::io::Write;

pub const ZIP: u32 = 0x1;
pub const ACTIVE_MASK: u32 = 0x2;
pub const BLOSC: u32 = 0x4;

pub const REAL_FILES: [&str; 3] = [
    "openusd_smoke_000003.vdb",
    "openusd_densityAndHeat.vdb",
    "openusd_smoke_000001_empty.vdb",
];

pub fn real_file(name: &str) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/volumes")
        .join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Codec {
    Lz4,
    Zlib,
    /// Any other blosc compressor code (0 blosclz, 2 snappy, 4 zstd); data is lz4.
    Code(u8),
}

#[derive(Clone, Debug)]
pub struct BloscOpts {
    pub codec: Codec,
    pub shuffle: bool,
    pub bitshuffle: bool,
    pub memcpyed: bool,
    pub dont_split: bool,
    /// Block size in bytes (clamped to the data size).
    pub blocksize: usize,
}

impl Default for BloscOpts {
    fn default() -> Self {
        BloscOpts {
            codec: Codec::Lz4,
            shuffle: true,
            bitshuffle: false,
            memcpyed: false,
            dont_split: false,
            blocksize: 1 << 20,
        }
    }
}

#[derive(Clone, Debug)]
pub enum Map {
    UniformScale(f64),
    ScaleTranslate([f64; 3], [f64; 3]),
    Translation([f64; 3]),
    /// Row-major 4x4 (OpenVDB's row-vector convention).
    Affine([f64; 16]),
    /// Written as this map type name with 100 bytes of zeros.
    Other(&'static str),
}

#[derive(Clone, Debug)]
pub struct Leaf {
    pub origin: [i32; 3],
    /// Bit n = voxel (n >> 6, (n >> 3) & 7, n & 7) is active.
    pub mask: [u64; 8],
    pub values: Vec<f32>,
}

#[derive(Clone, Debug)]
pub struct Tile {
    pub origin: [i32; 3],
    pub value: f32,
    pub active: bool,
}

#[derive(Clone, Debug)]
pub struct Grid {
    pub name: String,
    pub type_name: String,
    pub instance_parent: String,
    pub compression: u32,
    pub half: bool,
    pub blosc: BloscOpts,
    pub background: f32,
    pub map: Map,
    pub leaves: Vec<Leaf>,
    /// 8³ tiles inside node-4 nodes.
    pub tiles4: Vec<Tile>,
    /// 128³ tiles inside node-5 nodes.
    pub tiles5: Vec<Tile>,
    /// 4096³ tiles at the root.
    pub root_tiles: Vec<Tile>,
    /// Write root children's topology in reverse coordinate order (buffers stay sorted, which
    /// is the order OpenVDB reads them in).
    pub reverse_root_topology: bool,
}

impl Grid {
    pub fn float(name: &str) -> Grid {
        Grid {
            name: name.to_string(),
            type_name: "Tree_float_5_4_3".to_string(),
            instance_parent: String::new(),
            compression: BLOSC | ACTIVE_MASK,
            half: false,
            blosc: BloscOpts::default(),
            background: 0.0,
            map: Map::UniformScale(0.5),
            leaves: Vec::new(),
            tiles4: Vec::new(),
            tiles5: Vec::new(),
            root_tiles: Vec::new(),
            reverse_root_topology: false,
        }
    }
}

#[derive(Default, Debug)]
pub struct Stats {
    /// How many nodes were written with each metadata byte 0..=6.
    pub modes: [usize; 7],
    pub stored_chunks: usize,
    pub compressed_chunks: usize,
}

pub struct FileOpts {
    pub version: u32,
    pub has_offsets: bool,
}

impl Default for FileOpts {
    fn default() -> Self {
        FileOpts {
            version: 224,
            has_offsets: true,
        }
    }
}

pub fn write_file(grids: &[Grid], stats: &mut Stats) -> Vec<u8> {
    write_file_with(grids, &FileOpts::default(), stats)
}

pub fn write_file_with(grids: &[Grid], opts: &FileOpts, stats: &mut Stats) -> Vec<u8> {
    let mut o = Vec::new();
    o.extend_from_slice(&[0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0]);
    o.extend_from_slice(&opts.version.to_le_bytes());
    o.extend_from_slice(&10u32.to_le_bytes());
    o.extend_from_slice(&0u32.to_le_bytes());
    o.push(opts.has_offsets as u8);
    o.extend_from_slice(b"01234567-89ab-cdef-0123-456789abcdef");
    o.extend_from_slice(&1u32.to_le_bytes()); // file metadata: one string entry
    string(&mut o, "creator");
    string(&mut o, "string");
    o.extend_from_slice(&4u32.to_le_bytes());
    o.extend_from_slice(b"test");
    o.extend_from_slice(&(grids.len() as i32).to_le_bytes());
    for g in grids {
        string(&mut o, &g.name);
        let suffix = if g.half { "_HalfFloat" } else { "" };
        string(&mut o, &format!("{}{suffix}", g.type_name));
        string(&mut o, &g.instance_parent);
        let offsets_at = o.len();
        o.extend_from_slice(&[0u8; 24]);
        let grid_pos = o.len();
        o.extend_from_slice(&g.compression.to_le_bytes());
        o.extend_from_slice(&2u32.to_le_bytes());
        string(&mut o, "is_saved_as_half_float");
        string(&mut o, "bool");
        o.extend_from_slice(&1u32.to_le_bytes());
        o.push(g.half as u8);
        string(&mut o, "class");
        string(&mut o, "string");
        o.extend_from_slice(&10u32.to_le_bytes());
        o.extend_from_slice(b"fog volume");
        write_map(&mut o, &g.map);
        let block_pos = if g.instance_parent.is_empty() {
            write_tree(&mut o, g, stats)
        } else {
            o.len()
        };
        let end_pos = o.len();
        for (i, v) in [grid_pos, block_pos, end_pos].iter().enumerate() {
            o[offsets_at + 8 * i..offsets_at + 8 * i + 8]
                .copy_from_slice(&(*v as i64).to_le_bytes());
        }
    }
    o
}

fn string(o: &mut Vec<u8>, s: &str) {
    o.extend_from_slice(&(s.len() as u32).to_le_bytes());
    o.extend_from_slice(s.as_bytes());
}

fn f64s(o: &mut Vec<u8>, v: &[f64]) {
    for x in v {
        o.extend_from_slice(&x.to_le_bytes());
    }
}

fn write_map(o: &mut Vec<u8>, map: &Map) {
    match map {
        Map::UniformScale(s) => {
            string(o, "UniformScaleMap");
            f64s(o, &[*s, *s, *s, *s, *s, *s, 1.0 / s, 1.0 / s, 1.0 / s]);
            f64s(o, &[0.0; 6]);
        }
        Map::ScaleTranslate(s, t) => {
            string(o, "ScaleTranslateMap");
            f64s(o, t);
            f64s(o, s);
            f64s(o, s);
            f64s(o, &[0.0; 9]);
        }
        Map::Translation(t) => {
            string(o, "TranslationMap");
            f64s(o, t);
        }
        Map::Affine(m) => {
            string(o, "AffineMap");
            f64s(o, m);
        }
        Map::Other(name) => {
            string(o, name);
            o.extend_from_slice(&[0u8; 100]);
        }
    }
}

struct Node4 {
    values: Vec<f32>,
    value_mask: Vec<u64>,
    children: BTreeMap<usize, usize>, // slot -> leaf index
}

struct Node5 {
    values: Vec<f32>,
    value_mask: Vec<u64>,
    children: BTreeMap<usize, Node4>,
}

fn slot(origin: [i32; 3], p: [i32; 3], log2: u32, child_shift: u32) -> usize {
    let l: Vec<usize> = (0..3)
        .map(|a| ((p[a] - origin[a]) >> child_shift) as usize)
        .collect();
    (l[0] << (2 * log2)) | (l[1] << log2) | l[2]
}

fn set(mask: &mut [u64], n: usize) {
    mask[n / 64] |= 1 << (n % 64);
}

fn is_set(mask: &[u64], n: usize) -> bool {
    mask[n / 64] >> (n % 64) & 1 != 0
}

fn new_node5(bg: f32) -> Node5 {
    Node5 {
        values: vec![bg; 32768],
        value_mask: vec![0; 512],
        children: BTreeMap::new(),
    }
}

fn new_node4(bg: f32) -> Node4 {
    Node4 {
        values: vec![bg; 4096],
        value_mask: vec![0; 64],
        children: BTreeMap::new(),
    }
}

fn write_tree(o: &mut Vec<u8>, g: &Grid, stats: &mut Stats) -> usize {
    let root_key = |p: [i32; 3]| p.map(|v| v & !4095);
    let mut root: BTreeMap<[i32; 3], Node5> = BTreeMap::new();
    for (i, leaf) in g.leaves.iter().enumerate() {
        let k5 = root_key(leaf.origin);
        let n5 = root.entry(k5).or_insert_with(|| new_node5(g.background));
        let o4 = leaf.origin.map(|v| v & !127);
        let n4 = n5
            .children
            .entry(slot(k5, o4, 5, 7))
            .or_insert_with(|| new_node4(g.background));
        n4.children.insert(slot(o4, leaf.origin, 4, 3), i);
    }
    for t in &g.tiles4 {
        let k5 = root_key(t.origin);
        let n5 = root.entry(k5).or_insert_with(|| new_node5(g.background));
        let o4 = t.origin.map(|v| v & !127);
        let n4 = n5
            .children
            .entry(slot(k5, o4, 5, 7))
            .or_insert_with(|| new_node4(g.background));
        let n = slot(o4, t.origin, 4, 3);
        n4.values[n] = t.value;
        if t.active {
            set(&mut n4.value_mask, n);
        }
    }
    for t in &g.tiles5 {
        let k5 = root_key(t.origin);
        let n5 = root.entry(k5).or_insert_with(|| new_node5(g.background));
        let n = slot(k5, t.origin, 5, 7);
        n5.values[n] = t.value;
        if t.active {
            set(&mut n5.value_mask, n);
        }
    }

    o.extend_from_slice(&1i32.to_le_bytes());
    o.extend_from_slice(&g.background.to_le_bytes());
    o.extend_from_slice(&(g.root_tiles.len() as u32).to_le_bytes());
    o.extend_from_slice(&(root.len() as u32).to_le_bytes());
    for t in &g.root_tiles {
        for v in t.origin {
            o.extend_from_slice(&v.to_le_bytes());
        }
        o.extend_from_slice(&t.value.to_le_bytes());
        o.push(t.active as u8);
    }
    let mut order: Vec<(&[i32; 3], &Node5)> = root.iter().collect();
    if g.reverse_root_topology {
        order.reverse();
    }
    for (origin, n5) in order {
        for v in origin {
            o.extend_from_slice(&v.to_le_bytes());
        }
        let mut child_mask = vec![0u64; 512];
        for &n in n5.children.keys() {
            set(&mut child_mask, n);
        }
        masks(o, &child_mask);
        masks(o, &n5.value_mask);
        let vals: Vec<f32> = (0..32768)
            .map(|i| {
                if is_set(&child_mask, i) {
                    0.0
                } else {
                    n5.values[i]
                }
            })
            .collect();
        compressed_values(o, g, &vals, &n5.value_mask, &child_mask, stats);
        for n4 in n5.children.values() {
            let mut child_mask = vec![0u64; 64];
            for &n in n4.children.keys() {
                set(&mut child_mask, n);
            }
            masks(o, &child_mask);
            masks(o, &n4.value_mask);
            let vals: Vec<f32> = (0..4096)
                .map(|i| {
                    if is_set(&child_mask, i) {
                        0.0
                    } else {
                        n4.values[i]
                    }
                })
                .collect();
            compressed_values(o, g, &vals, &n4.value_mask, &child_mask, stats);
            for &leaf in n4.children.values() {
                masks(o, &g.leaves[leaf].mask);
            }
        }
    }
    let block_pos = o.len();
    for n5 in root.values() {
        for n4 in n5.children.values() {
            for &leaf in n4.children.values() {
                let leaf = &g.leaves[leaf];
                masks(o, &leaf.mask);
                compressed_values(o, g, &leaf.values, &leaf.mask, &[0u64; 8], stats);
            }
        }
    }
    block_pos
}

fn masks(o: &mut Vec<u8>, m: &[u64]) {
    for w in m {
        o.extend_from_slice(&w.to_le_bytes());
    }
}

fn half_round(v: f32) -> f32 {
    half::f16::from_f32(v).to_f32()
}

/// io::writeCompressedValues with MaskCompress.
fn compressed_values(
    o: &mut Vec<u8>,
    g: &Grid,
    src: &[f32],
    value_mask: &[u64],
    child_mask: &[u64],
    stats: &mut Stats,
) {
    let bg = g.background;
    let eq = |a: f32, b: f32| a == b; // isExactlyEqual
    let mut metadata = 6u8;
    let mut inactive = [bg, bg];
    if g.compression & ACTIVE_MASK != 0 {
        let mut unique = 0;
        for i in 0..src.len() {
            if is_set(value_mask, i) || is_set(child_mask, i) {
                continue;
            }
            if unique >= 3 {
                break;
            }
            let v = src[i];
            let is_new =
                !((unique > 0 && eq(v, inactive[0])) || (unique > 1 && eq(v, inactive[1])));
            if is_new {
                if unique < 2 {
                    inactive[unique] = v;
                }
                unique += 1;
            }
        }
        metadata = 0;
        if unique == 1 {
            if !eq(inactive[0], bg) {
                metadata = if eq(inactive[0], -bg) { 1 } else { 2 };
            }
        } else if unique == 2 {
            if !eq(inactive[0], bg) && !eq(inactive[1], bg) {
                metadata = 5;
            } else if eq(inactive[1], bg) {
                metadata = if eq(inactive[0], -bg) { 3 } else { 4 };
            } else if eq(inactive[0], bg) {
                inactive.swap(0, 1);
                metadata = if eq(inactive[0], -bg) { 3 } else { 4 };
            }
        } else if unique > 2 {
            metadata = 6;
        }
    }
    stats.modes[metadata as usize] += 1;
    o.push(metadata);
    if matches!(metadata, 2 | 4 | 5) {
        let t = |v: f32| if g.half { half_round(v) } else { v };
        o.extend_from_slice(&t(inactive[0]).to_le_bytes());
        if metadata == 5 {
            o.extend_from_slice(&t(inactive[1]).to_le_bytes());
        }
    }
    let mut out_vals: Vec<f32> = src.to_vec();
    if g.compression & ACTIVE_MASK != 0 && metadata != 6 {
        out_vals = (0..src.len())
            .filter(|&i| is_set(value_mask, i))
            .map(|i| src[i])
            .collect();
        if matches!(metadata, 3..=5) {
            let mut sel = vec![0u64; src.len() / 64];
            for i in 0..src.len() {
                if !is_set(value_mask, i) && eq(src[i], inactive[1]) {
                    set(&mut sel, i);
                }
            }
            masks(o, &sel);
        }
    }
    if g.half && out_vals.is_empty() {
        return; // HalfWriter writes nothing for zero values
    }
    let bytes: Vec<u8> = if g.half {
        out_vals
            .iter()
            .flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes())
            .collect()
    } else {
        out_vals.iter().flat_map(|v| v.to_le_bytes()).collect()
    };
    write_data(o, g, &bytes, stats);
}

fn write_data(o: &mut Vec<u8>, g: &Grid, bytes: &[u8], stats: &mut Stats) {
    let packed = if g.compression & BLOSC != 0 {
        if bytes.is_empty() {
            // c-blosc compresses 0 bytes to a bare header.
            let mut h = vec![2, 1, 0x21, 4];
            h.extend_from_slice(&0u32.to_le_bytes());
            h.extend_from_slice(&0u32.to_le_bytes());
            h.extend_from_slice(&16u32.to_le_bytes());
            Some(h)
        } else {
            Some(blosc_pack(bytes, &g.blosc))
        }
    } else if g.compression & ZIP != 0 {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(bytes).unwrap();
        let z = e.finish().unwrap();
        (z.len() < bytes.len()).then_some(z)
    } else {
        o.extend_from_slice(bytes);
        return;
    };
    match packed {
        Some(p) => {
            stats.compressed_chunks += 1;
            o.extend_from_slice(&(p.len() as i64).to_le_bytes());
            o.extend_from_slice(&p);
        }
        None => {
            stats.stored_chunks += 1;
            o.extend_from_slice(&(-(bytes.len() as i64)).to_le_bytes());
            o.extend_from_slice(bytes);
        }
    }
}

/// A blosc1 container with typesize 4, as c-blosc's blosc_compress_ctx lays it out.
pub fn blosc_pack(data: &[u8], b: &BloscOpts) -> Vec<u8> {
    let typesize = 4usize;
    let nbytes = data.len();
    let blocksize = b.blocksize.min(nbytes).max(1);
    let code = match b.codec {
        Codec::Lz4 => 1u8,
        Codec::Zlib => 3,
        Codec::Code(c) => c,
    };
    let mut flags =
        (code << 5) | if b.shuffle { 1 } else { 0 } | if b.dont_split { 0x10 } else { 0 };
    if b.bitshuffle {
        flags |= 0x4;
    }
    if b.memcpyed {
        flags |= 0x2;
    }
    let mut o = vec![2u8, 1, flags, typesize as u8];
    o.extend_from_slice(&(nbytes as u32).to_le_bytes());
    o.extend_from_slice(&(blocksize as u32).to_le_bytes());
    o.extend_from_slice(&0u32.to_le_bytes());
    if b.memcpyed {
        o.extend_from_slice(data);
    } else {
        let nblocks = nbytes.div_ceil(blocksize);
        let table = o.len();
        o.resize(table + 4 * nblocks, 0);
        for j in 0..nblocks {
            let start = o.len() as u32;
            o[table + 4 * j..table + 4 * j + 4].copy_from_slice(&start.to_le_bytes());
            let block = &data[j * blocksize..nbytes.min((j + 1) * blocksize)];
            let bsize = block.len();
            let leftover = bsize < blocksize;
            let shuffled = if b.shuffle {
                shuffle(typesize, block)
            } else {
                block.to_vec()
            };
            let splits = if !b.dont_split && bsize / typesize >= 128 && !leftover {
                typesize
            } else {
                1
            };
            let part_len = bsize / splits;
            for k in 0..splits {
                let part = &shuffled[k * part_len..(k + 1) * part_len];
                let comp = match b.codec {
                    Codec::Zlib => {
                        let mut e = flate2::write::ZlibEncoder::new(
                            Vec::new(),
                            flate2::Compression::default(),
                        );
                        e.write_all(part).unwrap();
                        e.finish().unwrap()
                    }
                    _ => lz4_flex::block::compress(part),
                };
                if comp.len() >= part_len {
                    o.extend_from_slice(&(part_len as u32).to_le_bytes());
                    o.extend_from_slice(part);
                } else {
                    o.extend_from_slice(&(comp.len() as u32).to_le_bytes());
                    o.extend_from_slice(&comp);
                }
            }
        }
    }
    let cbytes = o.len() as u32;
    o[12..16].copy_from_slice(&cbytes.to_le_bytes());
    o
}

fn shuffle(typesize: usize, block: &[u8]) -> Vec<u8> {
    let n = block.len() / typesize;
    let mut out = block.to_vec();
    for i in 0..n {
        for j in 0..typesize {
            out[j * n + i] = block[i * typesize + j];
        }
    }
    out
}

/// A leaf whose active voxels are those for which `active(n)` holds, with `value(n)` at every
/// voxel (inactive ones included, which drives the metadata-byte mode).
pub fn leaf(
    origin: [i32; 3],
    active: impl Fn(usize) -> bool,
    value: impl Fn(usize) -> f32,
) -> Leaf {
    let mut mask = [0u64; 8];
    for n in 0..512 {
        if active(n) {
            set(&mut mask, n);
        }
    }
    Leaf {
        origin,
        mask,
        values: (0..512).map(value).collect(),
    }
}

/// Expected active voxels of a grid (index -> value), 8³ tiles included (not 128³ tiles).
pub fn expected_voxels(g: &Grid) -> BTreeMap<[i32; 3], f32> {
    assert!(g.tiles5.is_empty() && g.root_tiles.iter().all(|t| !t.active));
    let round = |v: f32| if g.half { half_round(v) } else { v };
    let mut m = BTreeMap::new();
    for l in &g.leaves {
        for n in 0..512 {
            if is_set(&l.mask, n) {
                let p = [
                    l.origin[0] + (n >> 6) as i32,
                    l.origin[1] + ((n >> 3) & 7) as i32,
                    l.origin[2] + (n & 7) as i32,
                ];
                m.insert(p, round(l.values[n]));
            }
        }
    }
    for (tiles, dim) in [(&g.tiles4, 8)] {
        for t in tiles.iter().filter(|t| t.active) {
            for x in 0..dim {
                for y in 0..dim {
                    for z in 0..dim {
                        m.insert(
                            [t.origin[0] + x, t.origin[1] + y, t.origin[2] + z],
                            round(t.value),
                        );
                    }
                }
            }
        }
    }
    m
}
