//! A safe reader for the float-grid subset of OpenVDB (`.vdb`) files.
//!
//! It reads what Houdini, Blender/Mantaflow and OpenUSD write for smoke: file format versions
//! 222 to 225 with grid offsets, `Tree_float_5_4_3` grids (full float or saved as half float),
//! and expands one grid into a dense `f32` array over the index box of its active voxels.
//!
//! Implemented, following OpenVDB's `io/Archive.cc`, `io/File.cc`, `io/GridDescriptor.cc`,
//! `io/Compression.{h,cc}`, `tree/{RootNode,InternalNode,LeafNode}.h` and `math/Maps.h`:
//! - the file header (magic, versions, UUID), file metadata and grid descriptors, including the
//!   `\x1e N` suffix OpenVDB gives duplicate grid names (addressed as `name[N]`) and instances
//!   (grids that share the tree of an earlier grid);
//! - per-grid compression flags (none, zip, active mask, blosc), grid metadata, the linear
//!   transforms (`ScaleMap`, `UniformScaleMap`, `ScaleTranslateMap`, `UniformScaleTranslateMap`,
//!   `TranslationMap`, `AffineMap`, `UnitaryMap`);
//! - the tree: root tiles and children, internal nodes 5 and 4 (child and value masks, their
//!   compressed tile values) and 8³ leaves, with the per-node "metadata byte" mask compression
//!   (all seven modes; stored inactive values and the selection mask are parsed but not kept,
//!   because inactive voxels become the background in the dense grid);
//! - zip chunks (zlib via `flate2`) and blosc1 chunks (byte shuffle, split blocks, memcpyed
//!   chunks, the lz4 codec via `lz4_flex` and the zlib codec), half floats widened to `f32`.
//!
//! Refused, each with a one-line [`VdbError`]: other value types (vec3s, int32, ...) and tree
//! layouts, file versions before 222 (no per-node mask compression) and after 225 (unknown
//! changes), files written as streams without grid offsets, frustum and other non-linear maps,
//! singular transforms, blosc codecs other than lz4 and zlib (OpenVDB itself always writes lz4),
//! blosc bit-shuffle, and dense grids larger than [`Limits::max_dense_voxels`].
//!
//! Reading is two passes over the tree, as in OpenVDB: the topology (masks and tile values)
//! gives the active box and count, which are checked against [`Limits`] before the dense grid
//! is allocated; then the leaf buffers are decoded straight into it.
//!
//! Safety: every length, count and offset read from the file is checked against the bytes that
//! remain before anything is allocated from it, arithmetic on them is checked, decompressed sizes
//! must equal what the node needs (at most 32768 values), and the recursion depth is fixed by the
//! 5-4-3 layout. The `vdb-rs` crate (0.6.0) was rejected because it panics or aborts on bad input
//! (`unwrap`, `assert!`, `todo!`, `panic!` on unknown maps, allocations of file-given sizes).

use glam::{DAffine3, DMat3, DVec3, IVec3, UVec3};

/// Oldest file format version read: 222 introduced per-grid compression and the per-node
/// metadata byte; older files store nodes differently.
pub const MIN_FILE_VERSION: u32 = 222;
/// Newest file format version read (OpenVDB 12 writes 225); later versions may change the layout.
pub const MAX_FILE_VERSION: u32 = 225;

/// The only tree type read: float values, internal nodes of 32³ and 16³ children, 8³ leaves.
pub const FLOAT_TREE_TYPE: &str = "Tree_float_5_4_3";

const MAGIC: [u8; 8] = [0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0];
const HALF_FLOAT_SUFFIX: &str = "_HalfFloat";
/// OpenVDB separates a duplicate grid name from its index with ASCII "record separator".
const NAME_SEP: char = '\x1e';
const COMPRESS_ZIP: u32 = 0x1;
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
const COMPRESS_BLOSC: u32 = 0x4;
/// Per-node metadata byte values (io/Compression.h). 0 NO_MASK_OR_INACTIVE_VALS and
/// 1 NO_MASK_AND_MINUS_BG store nothing extra; the others below store inactive values and/or a
/// selection mask; 6 NO_MASK_AND_ALL_VALS stores every value and is the largest valid byte.
const NO_MASK_AND_ONE_INACTIVE_VAL: u8 = 2;
const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
const MASK_AND_ONE_INACTIVE_VAL: u8 = 4;
const MASK_AND_TWO_INACTIVE_VALS: u8 = 5;
const NO_MASK_AND_ALL_VALS: u8 = 6;
/// Edge of a root child (node 5) in voxels: 32 * 16 * 8.
const ROOT_CHILD_DIM_VOXELS: i64 = 4096;
const LEAF_VALUES: usize = 512;
const BLOSC_HEADER_BYTES: usize = 16;
const CODEC_LZ4: u8 = 1;
const CODEC_ZLIB: u8 = 2;

/// Everything that can go wrong; each message is one line naming the problem and, where it
/// helps, the byte offset in the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VdbError {
    #[error("not an OpenVDB file: it does not start with the magic bytes 20 42 44 56 00 00 00 00")]
    NotVdb,
    #[error(
        "OpenVDB file format version {0} is not supported; this reader handles versions {MIN_FILE_VERSION} to {MAX_FILE_VERSION}"
    )]
    UnsupportedVersion(u32),
    #[error(
        "the file has no grid offsets (it was written as a stream); only seekable .vdb files can be read"
    )]
    NoGridOffsets,
    #[error("truncated at byte {offset}: {what} needs {needed} bytes, {remaining} remain")]
    Truncated {
        offset: usize,
        what: &'static str,
        needed: u64,
        remaining: usize,
    },
    #[error("grid {name:?} not found; the file holds: {available}")]
    GridNotFound { name: String, available: String },
    #[error("grid {name:?} holds {value_type} values; only float grids can be read")]
    NotFloat { name: String, value_type: String },
    #[error("grid {name:?} has tree type {type_name}; only {FLOAT_TREE_TYPE} is supported")]
    UnsupportedTree { name: String, type_name: String },
    #[error(
        "grid {name:?} uses the transform {map}; only scale, translation and affine maps are supported"
    )]
    UnsupportedTransform { name: String, map: String },
    #[error("unsupported blosc codec {codec} (chunk at byte {offset}); OpenVDB writes lz4")]
    UnsupportedCodec { codec: &'static str, offset: usize },
    #[error("unsupported at byte {offset}: {what}")]
    Unsupported { offset: usize, what: String },
    #[error("invalid data at byte {offset}: {what}")]
    Invalid { offset: usize, what: String },
    #[error("grid {name:?} has more than {limit} active voxels, the dense-voxel limit")]
    TooManyActive { name: String, limit: u64 },
    #[error("dense grid would be {x}x{y}x{z} = {voxels} voxels, more than the limit of {limit}")]
    TooLarge {
        x: u64,
        y: u64,
        z: u64,
        voxels: u128,
        limit: u64,
    },
    #[error("could not allocate a dense grid of {voxels} voxels")]
    OutOfMemory { voxels: u64 },
}

fn invalid(offset: usize, what: impl Into<String>) -> VdbError {
    VdbError::Invalid {
        offset,
        what: what.into(),
    }
}

/// Bounds on what one read may allocate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Limits {
    /// Largest dense grid (`dims.x * dims.y * dims.z`, 4 bytes each) the reader will allocate.
    pub max_dense_voxels: u64,
}

impl Default for Limits {
    /// Two 256³ grids' worth: 33,554,432 voxels (128 MiB of `f32`).
    fn default() -> Self {
        Limits {
            max_dense_voxels: 2 * 256 * 256 * 256,
        }
    }
}

/// What the file says about one grid, without reading its tree.
#[derive(Debug, Clone, PartialEq)]
pub struct GridInfo {
    /// Name as users write it; a duplicate name's `\x1e N` suffix is shown as `name[N]`.
    pub name: String,
    /// Tree type without the `_HalfFloat` suffix, e.g. `Tree_float_5_4_3`.
    pub type_name: String,
    /// Short value type taken from the tree type, e.g. `float`, `vec3s`, `int32`.
    pub value_type: String,
    /// Whether floating-point values are stored as 16-bit halves.
    pub saved_as_half: bool,
    /// Name of the grid whose tree this grid shares, if it is an instance.
    pub instance_parent: Option<String>,
    /// Compression flags as OpenVDB prints them, e.g. `blosc + active mask`.
    pub compression: &'static str,
    /// The `class` metadata (`fog volume`, `level set`, ...), if present.
    pub grid_class: Option<String>,
    /// The writer's `file_voxel_count` metadata (active voxels), if present.
    pub file_active_voxels: Option<i64>,
    /// The writer's `file_bbox_min` / `file_bbox_max` metadata (inclusive index box), if present.
    pub file_index_bbox: Option<(IVec3, IVec3)>,
}

/// One float grid expanded into a dense array over the index box of its active voxels.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatGrid {
    /// Name as users write it (see [`GridInfo::name`]).
    pub name: String,
    /// Index of `values[0]`: the inclusive minimum corner of the active voxels (tiles included).
    pub index_min: IVec3,
    /// Dense size in voxels; all zero for a grid without active voxels.
    pub dims: UVec3,
    /// `dims.x * dims.y * dims.z` values, x fastest, then y, then z; inactive voxels hold
    /// `background`.
    pub values: Vec<f32>,
    /// The tree's background value.
    pub background: f32,
    /// Active voxels, counting each voxel an active tile covers.
    pub active_voxels: u64,
    /// Maps index coordinates (voxel centres at integers) to world coordinates.
    pub world_from_index: DAffine3,
    /// Whether the file stored the values as 16-bit halves (widened here).
    pub saved_as_half: bool,
    /// `none`, `zip`, `blosc(lz4)`, `blosc(zlib)`, `blosc(lz4+zlib)` or `blosc` (no chunk was
    /// actually compressed), for `smokeshadow info`.
    pub compression: &'static str,
}

impl FloatGrid {
    /// Dense value at an index coordinate, or `None` outside the dense box.
    pub fn value_at(&self, index: IVec3) -> Option<f32> {
        let local = (index.as_i64vec3()) - self.index_min.as_i64vec3();
        let dims = self.dims.as_i64vec3();
        if local.cmplt(glam::I64Vec3::ZERO).any() || local.cmpge(dims).any() {
            return None;
        }
        let i = (local.z * dims.y + local.y) * dims.x + local.x;
        self.values.get(usize::try_from(i).ok()?).copied()
    }
}

/// Lists the grids a file holds (name, value type, compression, writer's statistics).
pub fn list_grids(bytes: &[u8]) -> Result<Vec<GridInfo>, VdbError> {
    let file = parse_file(bytes)?;
    let mut infos = Vec::new();
    for d in &file.descriptors {
        let mut c = Cursor::at(bytes, d.grid_pos);
        let head = read_grid_head(&mut c, d)?;
        infos.push(GridInfo {
            name: display_name(&d.unique_name),
            type_name: d.type_name.clone(),
            value_type: value_type_of(&d.type_name),
            saved_as_half: head.half,
            instance_parent: (!d.instance_parent.is_empty())
                .then(|| display_name(&d.instance_parent)),
            compression: compression_flags_name(head.compression),
            grid_class: head.meta.class,
            file_active_voxels: head.meta.voxel_count,
            file_index_bbox: head.meta.bbox_min.zip(head.meta.bbox_max),
        });
    }
    Ok(infos)
}

/// Reads the float grid `name` (or `name[N]` for the N-th of several grids with that name)
/// into a dense grid.
pub fn read_float_grid(bytes: &[u8], name: &str, limits: &Limits) -> Result<FloatGrid, VdbError> {
    let file = parse_file(bytes)?;
    let d = find_descriptor(&file.descriptors, name).ok_or_else(|| VdbError::GridNotFound {
        name: name.to_string(),
        available: describe_grids(&file.descriptors),
    })?;
    check_float_type(d)?;
    let shown_name = display_name(&d.unique_name);
    let mut c = Cursor::at(bytes, d.grid_pos);
    let head = read_grid_head(&mut c, d)?;
    let world_from_index = read_transform(&mut c, &shown_name)?;

    // An instance shares the tree of its parent; the tree is stored (with the parent's own
    // compression settings) after the parent's metadata and transform.
    let (tree_cursor, tree_head) = if d.instance_parent.is_empty() {
        (c, head)
    } else {
        let parent_name = display_name(&d.instance_parent);
        let parent = find_descriptor(&file.descriptors, &parent_name)
            .filter(|p| p.instance_parent.is_empty())
            .ok_or_else(|| {
                invalid(
                    d.offset,
                    format!("instance parent {parent_name:?} is missing"),
                )
            })?;
        check_float_type(parent)?;
        let mut pc = Cursor::at(bytes, parent.grid_pos);
        let parent_head = read_grid_head(&mut pc, parent)?;
        read_transform(&mut pc, &parent_name)?;
        (pc, parent_head)
    };

    let mut tree = TreeReader::new(tree_cursor, &tree_head, &shown_name, limits);
    tree.read_topology()?;
    let mut dense = Dense::allocate(&tree.t, tree.background, limits)?;
    dense.fill_tiles(&tree.t.active_tiles)?;
    tree.read_leaf_buffers(&mut dense)?;
    let [x, y, z] = dense.dims.map(|d| d as u32); // checked against u32::MAX in allocate
    Ok(FloatGrid {
        name: shown_name,
        // Active voxels lie at or above i32 origins, so the minimum corner fits in i32.
        index_min: IVec3::from_array(dense.lo.map(|v| v as i32)),
        dims: UVec3::new(x, y, z),
        values: dense.values,
        background: tree.background,
        active_voxels: tree.t.active_voxels,
        world_from_index,
        saved_as_half: tree.half,
        compression: tree.compression_name(),
    })
}

// ---------------------------------------------------------------------------------------------
// Byte cursor

/// Reads little-endian values from a byte slice; every read checks the bytes that remain.
#[derive(Clone)]
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor at `pos`; positions past the end are clamped so later reads report truncation.
    fn at(bytes: &'a [u8], pos: usize) -> Self {
        Cursor {
            bytes,
            pos: pos.min(bytes.len()),
        }
    }

    fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }

    fn take(&mut self, len: u64, what: &'static str) -> Result<&'a [u8], VdbError> {
        let slice = usize::try_from(len)
            .ok()
            .and_then(|n| Some((n, self.pos.checked_add(n)?)))
            .and_then(|(n, end)| Some((n, self.bytes.get(self.pos..end)?)));
        match slice {
            Some((n, s)) => {
                self.pos += n;
                Ok(s)
            }
            None => Err(VdbError::Truncated {
                offset: self.pos,
                what,
                needed: len,
                remaining: self.remaining(),
            }),
        }
    }

    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], VdbError> {
        let at = self.pos;
        let s = self.take(N as u64, what)?;
        s.try_into().map_err(|_| invalid(at, what))
    }

    fn u8(&mut self, what: &'static str) -> Result<u8, VdbError> {
        Ok(self.array::<1>(what)?[0])
    }
    fn u32(&mut self, what: &'static str) -> Result<u32, VdbError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    fn i32(&mut self, what: &'static str) -> Result<i32, VdbError> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    fn i64(&mut self, what: &'static str) -> Result<i64, VdbError> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    fn f32(&mut self, what: &'static str) -> Result<f32, VdbError> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }
    fn dvec3(&mut self, what: &'static str) -> Result<DVec3, VdbError> {
        let mut v = [0.0; 3];
        for x in &mut v {
            *x = f64::from_le_bytes(self.array(what)?);
        }
        Ok(DVec3::from_array(v))
    }
    fn coord(&mut self, what: &'static str) -> Result<[i64; 3], VdbError> {
        Ok([
            self.i32(what)? as i64,
            self.i32(what)? as i64,
            self.i32(what)? as i64,
        ])
    }

    /// A string stored as a u32 byte count and that many bytes (not NUL-terminated).
    fn string(&mut self, what: &'static str) -> Result<String, VdbError> {
        let len = self.u32(what)?;
        Ok(String::from_utf8_lossy(self.take(len as u64, what)?).into_owned())
    }

    /// A node mask of `words` 64-bit words; bit `n` is bit `n % 64` of word `n / 64`.
    fn mask(&mut self, words: usize, what: &'static str) -> Result<Vec<u64>, VdbError> {
        let raw = self.take(words as u64 * 8, what)?;
        Ok(raw
            .chunks_exact(8)
            .map(|w| u64::from_le_bytes(w.try_into().unwrap_or([0; 8])))
            .collect())
    }
}

// ---------------------------------------------------------------------------------------------
// File header and grid descriptors

struct Descriptor {
    /// Byte offset of the descriptor, for messages.
    offset: usize,
    /// Name with OpenVDB's `\x1e N` duplicate suffix, if any.
    unique_name: String,
    /// Name without the suffix.
    grid_name: String,
    type_name: String,
    half_suffix: bool,
    instance_parent: String,
    grid_pos: usize,
}

struct VdbFile {
    descriptors: Vec<Descriptor>,
}

fn parse_file(bytes: &[u8]) -> Result<VdbFile, VdbError> {
    let mut c = Cursor::at(bytes, 0);
    if c.array::<8>("magic number").ok() != Some(MAGIC) {
        return Err(VdbError::NotVdb);
    }
    let version = c.u32("file format version")?;
    if !(MIN_FILE_VERSION..=MAX_FILE_VERSION).contains(&version) {
        return Err(VdbError::UnsupportedVersion(version));
    }
    let _library_major = c.u32("library major version")?;
    let _library_minor = c.u32("library minor version")?;
    if c.u8("has-grid-offsets flag")? == 0 {
        return Err(VdbError::NoGridOffsets);
    }
    c.take(36, "file UUID")?;
    read_metadata(&mut c)?; // file-level metadata: nothing in it is needed
    let count_at = c.pos;
    let count = c.i32("grid count")?;
    if count < 0 {
        return Err(invalid(count_at, format!("negative grid count {count}")));
    }
    let mut descriptors = Vec::new();
    for _ in 0..count {
        let offset = c.pos;
        let unique_name = c.string("grid name")?;
        let mut type_name = c.string("grid type")?;
        let half_suffix = type_name.ends_with(HALF_FLOAT_SUFFIX);
        if half_suffix {
            type_name.truncate(type_name.len() - HALF_FLOAT_SUFFIX.len());
        }
        let instance_parent = c.string("instance parent name")?;
        let grid_pos = c.i64("grid position")?;
        let _block_pos = c.i64("block position")?;
        let end_pos = c.i64("grid end position")?;
        // The next descriptor follows this grid; requiring it to lie ahead guarantees progress.
        if grid_pos < 0 || end_pos < c.pos as i64 {
            let what = format!("grid offsets {grid_pos}..{end_pos} are out of order");
            return Err(invalid(offset, what));
        }
        let furthest = grid_pos.max(end_pos) as u64;
        if furthest > bytes.len() as u64 {
            let (at, remaining) = (c.pos, c.remaining());
            let needed = furthest - at as u64;
            return Err(VdbError::Truncated {
                offset: at,
                what: "grid (by its end offset)",
                needed,
                remaining,
            });
        }
        let (grid_pos, end_pos) = (grid_pos as usize, end_pos as usize);
        let grid_name = match unique_name.find(NAME_SEP) {
            Some(i) => unique_name[..i].to_string(),
            None => unique_name.clone(),
        };
        descriptors.push(Descriptor {
            offset,
            unique_name,
            grid_name,
            type_name,
            half_suffix,
            instance_parent,
            grid_pos,
        });
        c = Cursor::at(bytes, end_pos);
    }
    Ok(VdbFile { descriptors })
}

/// `name\x1eN` is shown and addressed as `name[N]` (GridDescriptor::nameAsString).
fn display_name(unique: &str) -> String {
    match unique.split_once(NAME_SEP) {
        Some((base, n)) => format!("{base}[{n}]"),
        None => unique.to_string(),
    }
}

/// Finds a descriptor like OpenVDB's File::findDescriptor: a plain name picks the first grid
/// with that name; `name[N]` picks the grid whose unique name is `name\x1eN`.
fn find_descriptor<'d>(descriptors: &'d [Descriptor], name: &str) -> Option<&'d Descriptor> {
    let unique = match (name.strip_suffix(']'), name.find('[')) {
        (Some(body), Some(i)) if i < body.len() => {
            format!("{}{NAME_SEP}{}", &body[..i], &body[i + 1..])
        }
        _ => name.to_string(),
    };
    let with_name = |n: &str| {
        descriptors
            .iter()
            .filter(|d| d.grid_name == n)
            .collect::<Vec<_>>()
    };
    let mut candidates = with_name(name);
    if candidates.is_empty() {
        candidates = with_name(unique.split(NAME_SEP).next().unwrap_or_default());
    }
    if unique == name {
        candidates.first().copied()
    } else {
        candidates
            .into_iter()
            .find(|d| d.unique_name == unique || d.unique_name == name)
    }
}

fn describe_grids(descriptors: &[Descriptor]) -> String {
    if descriptors.is_empty() {
        return "no grids".to_string();
    }
    let parts: Vec<String> = descriptors
        .iter()
        .map(|d| {
            format!(
                "{} ({})",
                display_name(&d.unique_name),
                value_type_of(&d.type_name)
            )
        })
        .collect();
    parts.join(", ")
}

/// `Tree_vec3s_5_4_3` -> `vec3s`; other type names are returned whole.
fn value_type_of(type_name: &str) -> String {
    type_name
        .strip_prefix("Tree_")
        .and_then(|t| t.rsplitn(4, '_').nth(3))
        .unwrap_or(type_name)
        .to_string()
}

fn check_float_type(d: &Descriptor) -> Result<(), VdbError> {
    let name = display_name(&d.unique_name);
    let value_type = value_type_of(&d.type_name);
    if value_type != "float" {
        return Err(VdbError::NotFloat { name, value_type });
    }
    if d.type_name != FLOAT_TREE_TYPE {
        return Err(VdbError::UnsupportedTree {
            name,
            type_name: d.type_name.clone(),
        });
    }
    Ok(())
}

fn compression_flags_name(flags: u32) -> &'static str {
    match (
        flags & COMPRESS_BLOSC != 0,
        flags & COMPRESS_ZIP != 0,
        flags & COMPRESS_ACTIVE_MASK != 0,
    ) {
        (true, true, true) => "zip + blosc + active mask",
        (true, true, false) => "zip + blosc",
        (true, false, true) => "blosc + active mask",
        (true, false, false) => "blosc",
        (false, true, true) => "zip + active mask",
        (false, true, false) => "zip",
        (false, false, true) => "active mask",
        (false, false, false) => "none",
    }
}

// ---------------------------------------------------------------------------------------------
// Grid metadata and transform

#[derive(Default)]
struct GridMeta {
    saved_as_half: Option<bool>,
    class: Option<String>,
    voxel_count: Option<i64>,
    bbox_min: Option<IVec3>,
    bbox_max: Option<IVec3>,
}

struct GridHead {
    compression: u32,
    half: bool,
    meta: GridMeta,
}

/// Reads a metadata map (count, then name, type name, byte size, value) and keeps the few
/// entries this reader reports; the size prefix lets every other entry be skipped.
fn read_metadata(c: &mut Cursor) -> Result<GridMeta, VdbError> {
    let mut meta = GridMeta::default();
    let count = c.u32("metadata count")?;
    for _ in 0..count {
        let name = c.string("metadata name")?;
        let type_name = c.string("metadata type")?;
        let size = c.u32("metadata size")?;
        let value = c.take(size as u64, "metadata value")?;
        let le_i32 = |i: usize| {
            value
                .get(i..i + 4)
                .and_then(|b| b.try_into().ok())
                .map(i32::from_le_bytes)
        };
        match (name.as_str(), type_name.as_str(), value.len()) {
            ("is_saved_as_half_float", "bool", 1) => {
                meta.saved_as_half = value.first().map(|&b| b != 0)
            }
            ("class", "string", _) => {
                meta.class = Some(String::from_utf8_lossy(value).into_owned())
            }
            ("file_voxel_count", "int64", 8) => {
                meta.voxel_count = value.try_into().ok().map(i64::from_le_bytes);
            }
            ("file_bbox_min" | "file_bbox_max", "vec3i", 12) => {
                let v = le_i32(0)
                    .zip(le_i32(4))
                    .zip(le_i32(8))
                    .map(|((x, y), z)| IVec3::new(x, y, z));
                if name == "file_bbox_min" {
                    meta.bbox_min = v;
                } else {
                    meta.bbox_max = v;
                }
            }
            _ => {}
        }
    }
    Ok(meta)
}

/// Reads a grid's compression flags and metadata (the part of a grid before its transform).
fn read_grid_head(c: &mut Cursor, d: &Descriptor) -> Result<GridHead, VdbError> {
    let at = c.pos;
    let compression = c.u32("grid compression flags")?;
    if compression & !(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC) != 0 {
        return Err(VdbError::Unsupported {
            offset: at,
            what: format!("unknown compression flags {compression:#x}"),
        });
    }
    let meta = read_metadata(c)?;
    // OpenVDB decides from the grid's `is_saved_as_half_float` metadata, which it writes
    // together with the `_HalfFloat` type suffix; the suffix covers writers that omit it.
    let half = meta.saved_as_half.unwrap_or(d.half_suffix);
    Ok(GridHead {
        compression,
        half,
        meta,
    })
}

/// Reads a transform (map type name, then the map) as the index-to-world affine map.
/// OpenVDB multiplies row vectors: `world = index * M`, so the rows of M are our columns.
fn read_transform(c: &mut Cursor, grid: &str) -> Result<DAffine3, VdbError> {
    let at = c.pos;
    let map = c.string("transform map type")?;
    let affine = match map.as_str() {
        "ScaleMap" | "UniformScaleMap" => {
            let scale = c.dvec3("map scale")?;
            c.take(4 * 24, "map cached inverse terms")?; // voxel size, inverse scale, ...
            DAffine3::from_scale(scale)
        }
        "ScaleTranslateMap" | "UniformScaleTranslateMap" => {
            let translation = c.dvec3("map translation")?;
            let scale = c.dvec3("map scale")?;
            c.take(4 * 24, "map cached inverse terms")?;
            DAffine3::from_scale_rotation_translation(scale, glam::DQuat::IDENTITY, translation)
        }
        "TranslationMap" => DAffine3::from_translation(c.dvec3("map translation")?),
        "AffineMap" | "UnitaryMap" => {
            // A Mat4d: 16 doubles, row-major; rows 0-2 hold the linear part, row 3 the
            // translation, and column 3 must be (0, 0, 0, 1) for the map to be affine.
            let mut m = [0.0f64; 16];
            for x in &mut m {
                *x = f64::from_le_bytes(c.array("affine matrix")?);
            }
            let row = |i: usize| DVec3::new(m[4 * i], m[4 * i + 1], m[4 * i + 2]);
            if [m[3], m[7], m[11], m[15]] != [0.0, 0.0, 0.0, 1.0] {
                let what = "the AffineMap matrix is projective, not affine";
                return Err(invalid(at, what));
            }
            DAffine3::from_mat3_translation(DMat3::from_cols(row(0), row(1), row(2)), row(3))
        }
        _ => {
            return Err(VdbError::UnsupportedTransform {
                name: grid.to_string(),
                map,
            });
        }
    };
    check_transform(affine, at)
}

fn check_transform(affine: DAffine3, at: usize) -> Result<DAffine3, VdbError> {
    let det = affine.matrix3.determinant();
    if !affine.is_finite() || !det.is_normal() {
        return Err(invalid(at, "the transform is singular or not finite"));
    }
    Ok(affine)
}

// ---------------------------------------------------------------------------------------------
// Tree reading: topology, then leaf buffers

/// Reads one grid's tree. It keeps what OpenVDB keeps on its stream while reading a tree
/// (compression flags, half flag, background), buffers reused across nodes so that reading
/// allocates a fixed amount per grid, and the topology read so far.
struct TreeReader<'a> {
    c: Cursor<'a>,
    compression: u32,
    half: bool,
    background: f32,
    /// Blosc codecs met so far (CODEC_LZ4 | CODEC_ZLIB), for [`FloatGrid::compression`].
    codecs: u8,
    /// Decoded bytes of one chunk (at most 32768 values * 4 bytes).
    bytes: Vec<u8>,
    /// One blosc block before unshuffling.
    block: Vec<u8>,
    /// The values of one chunk, then only the active ones (see `read_active_values`).
    values: Vec<f32>,
    t: Topology,
}

struct Leaf {
    origin: [i64; 3],
    mask: [u64; 8],
}

struct Tile {
    origin: [i64; 3],
    dim_voxels: i64,
    value: f32,
}

struct RootChild {
    origin: [i64; 3],
    leaves: std::ops::Range<usize>,
}

#[derive(Default)]
struct Topology {
    grid: String,
    max_active_voxels: u64,
    leaves: Vec<Leaf>,
    active_tiles: Vec<Tile>,
    root_children: Vec<RootChild>,
    active_voxels: u64,
    /// Inclusive index box of active voxels, if any.
    bbox: Option<([i64; 3], [i64; 3])>,
}

impl Topology {
    fn add_active(&mut self, voxels: u64, lo: [i64; 3], hi: [i64; 3]) -> Result<(), VdbError> {
        self.active_voxels = self.active_voxels.saturating_add(voxels);
        // The dense grid holds at least every active voxel, so this bounds the tile list too.
        if self.active_voxels > self.max_active_voxels {
            let (name, limit) = (self.grid.clone(), self.max_active_voxels);
            return Err(VdbError::TooManyActive { name, limit });
        }
        let (a, b) = self.bbox.unwrap_or((lo, hi));
        self.bbox = Some((
            [0, 1, 2].map(|i| a[i].min(lo[i])),
            [0, 1, 2].map(|i| b[i].max(hi[i])),
        ));
        Ok(())
    }

    fn add_tile(&mut self, origin: [i64; 3], dim_voxels: i64, value: f32) -> Result<(), VdbError> {
        let hi = origin.map(|o| o + dim_voxels - 1);
        self.add_active((dim_voxels as u64).pow(3), origin, hi)?;
        self.active_tiles.push(Tile {
            origin,
            dim_voxels,
            value,
        });
        Ok(())
    }
}

/// Internal node levels of the 5-4-3 tree: node 5 has 32³ children of 128³ voxels, node 4 has
/// 16³ leaves of 8³ voxels.
#[derive(Clone, Copy, PartialEq)]
enum Level {
    Node5,
    Node4,
}

impl Level {
    fn log2_dim(self) -> u32 {
        if self == Level::Node5 { 5 } else { 4 }
    }
    fn child_log2_voxels(self) -> u32 {
        if self == Level::Node5 { 7 } else { 3 }
    }
    /// Global origin of child slot `n` (InternalNode::offsetToGlobalCoord).
    fn child_origin(self, origin: [i64; 3], n: usize) -> [i64; 3] {
        let (log2, shift) = (self.log2_dim(), self.child_log2_voxels());
        let local = [
            n >> (2 * log2),
            (n >> log2) & ((1 << log2) - 1),
            n & ((1 << log2) - 1),
        ];
        [0, 1, 2].map(|a| origin[a] + ((local[a] as i64) << shift))
    }
}

fn bit(mask: &[u64], i: usize) -> bool {
    mask.get(i / 64).is_some_and(|w| (w >> (i % 64)) & 1 != 0)
}

/// Positions of the set bits of a mask, in increasing order.
fn set_bits(mask: &[u64]) -> impl Iterator<Item = usize> + '_ {
    mask.iter().enumerate().flat_map(|(w, &word)| {
        let mut rest = word;
        std::iter::from_fn(move || {
            (rest != 0).then(|| {
                let b = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                w * 64 + b
            })
        })
    })
}

fn count_ones(mask: &[u64]) -> usize {
    mask.iter().map(|w| w.count_ones() as usize).sum()
}

impl<'a> TreeReader<'a> {
    fn new(c: Cursor<'a>, head: &GridHead, grid: &str, limits: &Limits) -> Self {
        let max_active_voxels = limits.max_dense_voxels;
        let t = Topology {
            grid: grid.to_string(),
            max_active_voxels,
            ..Default::default()
        };
        let (compression, half, background, codecs) = (head.compression, head.half, 0.0, 0);
        let bufs = (Vec::new(), Vec::new(), Vec::new());
        let (bytes, block, values) = bufs;
        TreeReader {
            c,
            compression,
            half,
            background,
            codecs,
            bytes,
            block,
            values,
            t,
        }
    }

    fn compression_name(&self) -> &'static str {
        if self.compression & COMPRESS_BLOSC != 0 {
            match self.codecs {
                CODEC_LZ4 => "blosc(lz4)",
                CODEC_ZLIB => "blosc(zlib)",
                0 => "blosc",
                _ => "blosc(lz4+zlib)",
            }
        } else if self.compression & COMPRESS_ZIP != 0 {
            "zip"
        } else {
            "none"
        }
    }

    /// Reads the tree topology (Tree::readTopology): buffer count, root background, root tiles
    /// and children, internal nodes with their tile values, and leaf value masks.
    fn read_topology(&mut self) -> Result<(), VdbError> {
        let _buffer_count = self.c.i32("tree buffer count")?; // 1; OpenVDB only warns otherwise
        self.background = self.c.f32("background value")?;
        let tile_count = self.c.u32("root tile count")?;
        let child_count = self.c.u32("root child count")?;
        let mut keys = Vec::new();
        for _ in 0..tile_count {
            let origin = self.root_origin("root tile origin")?;
            let value = self.c.f32("root tile value")?;
            if self.c.u8("root tile active flag")? != 0 {
                self.t.add_tile(origin, ROOT_CHILD_DIM_VOXELS, value)?;
            }
            keys.push(origin);
        }
        for _ in 0..child_count {
            let origin = self.root_origin("root child origin")?;
            let first = self.t.leaves.len();
            self.read_internal(Level::Node5, origin)?;
            let leaves = first..self.t.leaves.len();
            self.t.root_children.push(RootChild { origin, leaves });
            keys.push(origin);
        }
        // The root keeps its entries in a map: a repeated origin would be dropped there and its
        // buffers never read, so the file is refused instead.
        keys.sort_unstable();
        if let Some(w) = keys.windows(2).find(|w| w.first() == w.get(1)) {
            let what = format!("the root holds two entries at {:?}", w.first());
            return Err(invalid(self.c.pos, what));
        }
        Ok(())
    }

    fn root_origin(&mut self, what: &'static str) -> Result<[i64; 3], VdbError> {
        let at = self.c.pos;
        let origin = self.c.coord(what)?;
        if origin.iter().any(|o| o % ROOT_CHILD_DIM_VOXELS != 0) {
            let what = format!("root entry origin {origin:?} is not a multiple of 4096");
            return Err(invalid(at, what));
        }
        Ok(origin)
    }

    /// Reads an internal node's topology (InternalNode::readTopology). Node 5 calls this for
    /// its node-4 children and node 4 reads leaves, so the recursion is at most two deep.
    fn read_internal(&mut self, level: Level, origin: [i64; 3]) -> Result<(), VdbError> {
        let slots = 1usize << (3 * level.log2_dim());
        let child_mask = self.c.mask(slots / 64, "internal node child mask")?;
        let value_mask = self.c.mask(slots / 64, "internal node value mask")?;
        self.read_active_values(&value_mask, slots)?;
        // Active values come in value-mask order; a slot that also has a child is a child.
        let dim_voxels = 1 << level.child_log2_voxels();
        for (n, &value) in set_bits(&value_mask).zip(&self.values) {
            if !bit(&child_mask, n) {
                self.t
                    .add_tile(level.child_origin(origin, n), dim_voxels, value)?;
            }
        }
        for n in set_bits(&child_mask) {
            let child = level.child_origin(origin, n);
            match level {
                Level::Node5 => self.read_internal(Level::Node4, child)?,
                Level::Node4 => self.read_leaf_topology(child)?,
            }
        }
        Ok(())
    }

    /// Reads a leaf's value mask (LeafNode::readTopology) and records its active voxels.
    fn read_leaf_topology(&mut self, origin: [i64; 3]) -> Result<(), VdbError> {
        let mut mask = [0u64; 8];
        for (m, w) in mask.iter_mut().zip(self.c.mask(8, "leaf value mask")?) {
            *m = w;
        }
        let active = count_ones(&mask) as u64;
        if active > 0 {
            // Word x holds slice x of the leaf, byte y of a word row y, bit z of a byte column z.
            let xs = (0..8u32).filter(|&x| mask[x as usize] != 0);
            let (x_lo, x_hi) = xs.fold((7, 0), |(l, h), x| (x.min(l), x.max(h)));
            let rows = mask.iter().fold(0u64, |a, &w| a | w);
            let columns = rows.to_le_bytes().iter().fold(0u8, |a, &b| a | b);
            let lo = [x_lo, rows.trailing_zeros() / 8, columns.trailing_zeros()];
            let hi = [
                x_hi,
                (63 - rows.leading_zeros()) / 8,
                7 - columns.leading_zeros(),
            ];
            let at = |v: [u32; 3]| [0, 1, 2].map(|a| origin[a] + v[a] as i64);
            self.t.add_active(active, at(lo), at(hi))?;
        }
        self.t.leaves.push(Leaf { origin, mask });
        Ok(())
    }

    /// Reads the leaf buffers (Tree::readBuffers) and writes active values into the dense grid.
    /// The root visits its children in coordinate order (it keeps them in a std::map), each
    /// internal node in child-mask order, which is the order of `leaves` within a root child.
    fn read_leaf_buffers(&mut self, dense: &mut Dense) -> Result<(), VdbError> {
        self.t.root_children.sort_by_key(|r| r.origin);
        // Strides of the dense array, x fastest; offsets are computed in i64 and checked.
        let (stride_y, stride_z) = (dense.dims[0] as i64, (dense.dims[0] * dense.dims[1]) as i64);
        for child in 0..self.t.root_children.len() {
            let range = self
                .t
                .root_children
                .get(child)
                .map_or(0..0, |r| r.leaves.clone());
            for l in range {
                let Some(&Leaf { origin, mask }) = self.t.leaves.get(l) else {
                    continue;
                };
                // A seekable OpenVDB reader skips this copy of the mask and keeps the topology's.
                self.c.take(64, "leaf value mask (buffer copy)")?;
                self.read_active_values(&mask, LEAF_VALUES)?;
                let o = [0, 1, 2].map(|a| origin[a] - dense.lo[a]);
                let base = o[2] * stride_z + o[1] * stride_y + o[0];
                let mut active = self.values.iter();
                for (x, &word) in mask.iter().enumerate() {
                    let mut rest = word;
                    while rest != 0 {
                        let n = rest.trailing_zeros() as i64;
                        rest &= rest - 1;
                        let i = base + x as i64 + (n >> 3) * stride_y + (n & 7) * stride_z;
                        let slot = usize::try_from(i)
                            .ok()
                            .and_then(|i| dense.values.get_mut(i));
                        let (Some(slot), Some(&v)) = (slot, active.next()) else {
                            return Err(invalid(
                                self.c.pos,
                                "internal error: voxel outside the box",
                            ));
                        };
                        *slot = v;
                    }
                }
            }
        }
        Ok(())
    }

    /// Reads one node's value buffer (io::readCompressedValues) and leaves in `self.values` the
    /// values of the positions set in `value_mask`, in increasing order. The metadata byte, up
    /// to two inactive values and the selection mask are parsed to stay in step with the
    /// stream, but inactive values are not kept: the dense grid holds the background for them.
    fn read_active_values(
        &mut self,
        value_mask: &[u64],
        node_values: usize,
    ) -> Result<(), VdbError> {
        let c = &mut self.c;
        let at = c.pos;
        let metadata = c.u8("per-node compression byte")?;
        if metadata > NO_MASK_AND_ALL_VALS {
            let what = format!("per-node compression byte {metadata} is not 0..=6");
            return Err(invalid(at, what));
        }
        let (one, two) = (MASK_AND_ONE_INACTIVE_VAL, MASK_AND_TWO_INACTIVE_VALS);
        if matches!(metadata, NO_MASK_AND_ONE_INACTIVE_VAL) || metadata == one || metadata == two {
            // Inactive values are always stored full size, even for half-float grids.
            c.take(if metadata == two { 8 } else { 4 }, "inactive values")?;
        }
        if metadata == MASK_AND_NO_INACTIVE_VALS || metadata == one || metadata == two {
            c.take(node_values as u64 / 8, "selection mask")?;
        }
        let mask_compressed =
            self.compression & COMPRESS_ACTIVE_MASK != 0 && metadata != NO_MASK_AND_ALL_VALS;
        let active = count_ones(value_mask).min(node_values);
        let count = if mask_compressed { active } else { node_values };
        self.read_data(count)?;
        if count != active {
            // All values were stored: keep the active ones, compacting in place (k <= n).
            let v = &mut self.values;
            let mut k = 0;
            for (w, &word) in value_mask.iter().enumerate() {
                let mut rest = word;
                while rest != 0 {
                    let n = w * 64 + rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    if n < v.len() && k < n {
                        v[k] = v[n];
                    }
                    k += 1;
                }
            }
            v.truncate(k);
        }
        Ok(())
    }

    /// Reads `count` values (io::readData, or HalfReader for half floats) into `self.values`.
    fn read_data(&mut self, count: usize) -> Result<(), VdbError> {
        self.values.clear();
        // HalfReader returns before touching the stream when there is nothing to read.
        if self.half && count == 0 {
            return Ok(());
        }
        self.read_chunk(count * if self.half { 2 } else { 4 })?;
        // While loops over plain indices (all < len): this runs for every value of every
        // leaf, and the crate may be built without optimisation.
        let (b, v) = (&self.bytes, &mut self.values);
        let mut i = 0;
        if self.half {
            while i + 2 <= b.len() {
                v.push(f16_to_f32(u16::from_le_bytes([b[i], b[i + 1]])));
                i += 2;
            }
        } else {
            while i + 4 <= b.len() {
                v.push(f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]));
                i += 4;
            }
        }
        Ok(())
    }

    /// Reads `nbytes` bytes of values into `self.bytes`: raw, or a zip / blosc chunk that
    /// starts with an i64 byte count (negative: the bytes follow uncompressed).
    fn read_chunk(&mut self, nbytes: usize) -> Result<(), VdbError> {
        let at = self.c.pos;
        let stored = if self.compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
            self.c.take(nbytes as u64, "uncompressed values")?
        } else {
            let size = self.c.i64("compressed chunk size")?;
            if size > 0 {
                let src = self.c.take(size as u64, "compressed chunk")?;
                // OpenVDB prefers blosc when both flags are set.
                if self.compression & COMPRESS_BLOSC != 0 {
                    let (out, block) = (&mut self.bytes, &mut self.block);
                    self.codecs |= blosc_decompress(src, nbytes, at, out, block)?;
                } else {
                    self.bytes.resize(nbytes, 0);
                    zlib_decompress(src, &mut self.bytes, at)?;
                }
                return Ok(());
            }
            if size.unsigned_abs() != nbytes as u64 {
                let n = size.unsigned_abs();
                let what = format!("stored chunk holds {n} bytes, the node needs {nbytes}");
                return Err(invalid(at, what));
            }
            self.c.take(nbytes as u64, "stored chunk")?
        };
        self.bytes.clear();
        self.bytes.extend_from_slice(stored);
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Zip and blosc chunks, half floats

/// Inflates a zlib stream into exactly `out.len()` bytes.
fn zlib_decompress(src: &[u8], out: &mut [u8], at: usize) -> Result<(), VdbError> {
    let mut z = flate2::Decompress::new(true);
    z.decompress(src, out, flate2::FlushDecompress::Finish)
        .map_err(|e| invalid(at, format!("corrupt zlib data: {e}")))?;
    if z.total_out() != out.len() as u64 {
        let (got, want) = (z.total_out(), out.len());
        let what = format!("zlib data inflates to {got} bytes, the node needs {want}");
        return Err(invalid(at, what));
    }
    Ok(())
}

fn unsupported(offset: usize, what: impl Into<String>) -> VdbError {
    VdbError::Unsupported {
        offset,
        what: what.into(),
    }
}

/// Decompresses a blosc1 container (c-blosc's blosc_decompress_ctx) into exactly `expected`
/// bytes; returns the codec bits it met.
fn blosc_decompress(
    src: &[u8],
    expected: usize,
    at: usize,
    out: &mut Vec<u8>,
    block: &mut Vec<u8>,
) -> Result<u8, VdbError> {
    let header = src
        .get(..BLOSC_HEADER_BYTES)
        .and_then(|h| <[u8; BLOSC_HEADER_BYTES]>::try_from(h).ok());
    let Some(h) = header else {
        let what = "blosc chunk is shorter than its 16-byte header";
        return Err(invalid(at, what));
    };
    let le = |i: usize| u32::from_le_bytes([h[i], h[i + 1], h[i + 2], h[i + 3]]) as usize;
    let (version, codec_version, flags, typesize) = (h[0], h[1], h[2], h[3] as usize);
    let (nbytes, blocksize, cbytes) = (le(4), le(8), le(12));
    if nbytes != expected {
        let what = format!("blosc chunk holds {nbytes} bytes, the node needs {expected}");
        return Err(invalid(at, what));
    }
    // Every byte is overwritten below, so only the length changes (no re-zeroing per chunk).
    out.resize(expected, 0);
    if nbytes == 0 {
        return Ok(0);
    }
    if version != 2 {
        let what = format!("blosc format version {version} (only 2, c-blosc 1.x)");
        return Err(unsupported(at, what));
    }
    if flags & 0x08 != 0 {
        let what = format!("blosc flags {flags:#04x} from a newer blosc");
        return Err(unsupported(at, what));
    }
    if typesize == 0 || blocksize == 0 || blocksize > expected {
        let what = format!("blosc typesize {typesize} or block size {blocksize} is invalid");
        return Err(invalid(at, what));
    }
    let Some(src) = src.get(..cbytes).filter(|_| cbytes >= BLOSC_HEADER_BYTES) else {
        let what = format!(
            "blosc header claims {cbytes} bytes, the chunk has {}",
            src.len()
        );
        return Err(invalid(at, what));
    };
    if flags & 0x02 != 0 {
        // Memcpyed: the data follows the header unchanged (and unshuffled).
        let Some(data) = src.get(BLOSC_HEADER_BYTES..).filter(|d| d.len() == nbytes) else {
            let what = "blosc memcpyed chunk size does not match its header";
            return Err(invalid(at, what));
        };
        out.copy_from_slice(data);
        return Ok(0);
    }
    let (codec, codec_bit) = match flags >> 5 {
        1 => ("lz4", CODEC_LZ4),
        3 => ("zlib", CODEC_ZLIB),
        other => {
            let codec = ["blosclz", "lz4", "snappy", "zlib", "zstd"].get(other as usize);
            let codec = codec.copied().unwrap_or("with an unknown code");
            return Err(VdbError::UnsupportedCodec { codec, offset: at });
        }
    };
    if codec_version != 1 {
        let what = format!("blosc {codec} format version {codec_version} (only 1)");
        return Err(unsupported(at, what));
    }
    if flags & 0x04 != 0 && blocksize >= typesize {
        let what = "blosc bit-shuffle filter (OpenVDB writes byte shuffle)";
        return Err(unsupported(at, what));
    }
    let shuffled = flags & 0x01 != 0 && typesize > 1;
    let dont_split = flags & 0x10 != 0;
    let nblocks = nbytes.div_ceil(blocksize);
    let Some(starts) = src.get(BLOSC_HEADER_BYTES..BLOSC_HEADER_BYTES + 4 * nblocks) else {
        let what = format!("blosc table of {nblocks} blocks does not fit the chunk");
        return Err(invalid(at, what));
    };
    let read_u32 = |o: usize| {
        src.get(o..o.checked_add(4)?)
            .and_then(|b| b.try_into().ok())
    };
    block.resize(blocksize, 0);
    for (j, start) in starts.chunks_exact(4).enumerate() {
        let first = j * blocksize;
        let bsize = blocksize.min(nbytes - first);
        // A full block of at least 128 elements was compressed as one stream per byte of the
        // element (after shuffling), unless the writer said not to split.
        let split = !dont_split && typesize <= 16 && bsize / typesize >= 128 && bsize == blocksize;
        let splits = if split { typesize } else { 1 };
        let split_bytes = bsize / splits;
        let mut offset = u32::from_le_bytes([start[0], start[1], start[2], start[3]]) as usize;
        let target = if shuffled {
            block.get_mut(..bsize)
        } else {
            out.get_mut(first..first + bsize)
        };
        let bad = |k: usize| {
            invalid(
                at,
                format!("blosc block {j} split {k} lies outside the chunk"),
            )
        };
        let target = target.ok_or_else(|| bad(0))?;
        for k in 0..splits {
            let csize = read_u32(offset)
                .map(u32::from_le_bytes)
                .ok_or_else(|| bad(k))? as usize;
            let from = offset.checked_add(4);
            let end = from.and_then(|f| f.checked_add(csize));
            let data = from.zip(end).and_then(|(f, e)| src.get(f..e));
            let dst = target.get_mut(k * split_bytes..(k + 1) * split_bytes);
            let (Some(data), Some(dst)) = (data, dst) else {
                return Err(bad(k));
            };
            offset = end.unwrap_or(usize::MAX);
            if csize == split_bytes {
                dst.copy_from_slice(data); // stored: the compressor could not shrink it
            } else if codec_bit == CODEC_ZLIB {
                zlib_decompress(data, dst, at)?;
            } else {
                let produced = lz4_flex::block::decompress_into(data, dst).map_err(|e| {
                    invalid(at, format!("corrupt lz4 data in blosc block {j}: {e}"))
                })?;
                if produced != split_bytes {
                    let what =
                        format!("blosc block {j} holds {produced} bytes, expected {split_bytes}");
                    return Err(invalid(at, what));
                }
            }
        }
        if shuffled {
            let (Some(from), Some(to)) = (block.get(..bsize), out.get_mut(first..first + bsize))
            else {
                return Err(bad(0));
            };
            unshuffle(typesize, from, to);
        }
    }
    Ok(codec_bit)
}

/// Undoes blosc's byte shuffle: byte `j` of element `i` was stored at `j * elements + i`;
/// trailing bytes that do not fill an element were left in place.
fn unshuffle(typesize: usize, from: &[u8], to: &mut [u8]) {
    let len = from.len().min(to.len());
    let elements = len / typesize;
    // Plain index loops (all indices < elements * typesize <= len): this runs for every leaf,
    // and the crate may be built without optimisation.
    let mut j = 0;
    while j < typesize {
        let (mut i, plane) = (0, j * elements);
        while i < elements {
            to[i * typesize + j] = from[plane + i];
            i += 1;
        }
        j += 1;
    }
    let tail = elements * typesize;
    if let (Some(t), Some(f)) = (to.get_mut(tail..len), from.get(tail..len)) {
        t.copy_from_slice(f);
    }
}

/// Widens an IEEE 754 binary16 value (as Imath's half does, keeping NaN payloads).
fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h as u32) & 0x8000) << 16;
    let exponent = ((h >> 10) & 0x1f) as u32;
    let mantissa = (h & 0x3ff) as u32;
    match exponent {
        0 => {
            // Zero or subnormal: mantissa * 2^-24 is exact in f32.
            let magnitude = mantissa as f32 * (1.0 / 16_777_216.0);
            if sign != 0 { -magnitude } else { magnitude }
        }
        31 => f32::from_bits(sign | 0x7f80_0000 | (mantissa << 13)),
        _ => f32::from_bits(sign | ((exponent + 112) << 23) | (mantissa << 13)),
    }
}

// ---------------------------------------------------------------------------------------------
// Dense grid

struct Dense {
    /// Index of `values[0]`.
    lo: [i64; 3],
    dims: [u64; 3],
    values: Vec<f32>,
}

impl Dense {
    /// Allocates the dense grid over the active box, filled with the background.
    fn allocate(t: &Topology, background: f32, limits: &Limits) -> Result<Dense, VdbError> {
        let Some((lo, hi)) = t.bbox else {
            return Ok(Dense {
                lo: [0; 3],
                dims: [0; 3],
                values: Vec::new(),
            });
        };
        let dims = [0, 1, 2].map(|a| (hi[a] - lo[a] + 1) as u64);
        let voxels = dims.iter().map(|&d| d as u128).product::<u128>();
        let limit = limits.max_dense_voxels;
        let too_large = VdbError::TooLarge {
            x: dims[0],
            y: dims[1],
            z: dims[2],
            voxels,
            limit,
        };
        if voxels > limit as u128 || dims.iter().any(|&d| d > u32::MAX as u64) {
            return Err(too_large);
        }
        let count = usize::try_from(voxels).map_err(|_| too_large)?;
        let mut values = Vec::new();
        let oom = VdbError::OutOfMemory {
            voxels: count as u64,
        };
        values.try_reserve_exact(count).map_err(|_| oom)?;
        values.resize(count, background);
        Ok(Dense { lo, dims, values })
    }

    /// Fills the active tiles' voxels, row by row.
    fn fill_tiles(&mut self, tiles: &[Tile]) -> Result<(), VdbError> {
        let (lo, dims) = (self.lo, self.dims);
        for tile in tiles {
            let (d, [x, y0, z0]) = (tile.dim_voxels, tile.origin);
            for z in z0..z0 + d {
                for y in y0..y0 + d {
                    let l = [x - lo[0], y - lo[1], z - lo[2]].map(|v| v as u64);
                    let start = (l[2] * dims[1] + l[1]) * dims[0] + l[0];
                    let row = usize::try_from(start)
                        .ok()
                        .and_then(|s| self.values.get_mut(s..s + d as usize));
                    row.ok_or_else(|| invalid(0, "internal error: tile outside the box"))?
                        .fill(tile.value);
                }
            }
        }
        Ok(())
    }
}
