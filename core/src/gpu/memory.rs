//! Memory accounting from what is actually allocated.
//!
//! Every texture and buffer a shadow technique owns is created through a [`MemoryLedger`], which
//! records its size computed from the descriptor wgpu received (format block size x extent x
//! layers x mips, or the buffer size). The bytes a technique reports are the ledger's sum, so the
//! number cannot drift from the allocations: nothing is declared, a buffer is counted by being
//! created here (`tests/memory.rs` holds every technique's ledger to the allocations the GPU's
//! own allocator reports under its labels).
//!
//! **What is charged.** A technique's *resident* bytes are everything it holds at its peak
//! ([`MemoryLedger::peak_bytes`]): what the lookup reads (persistent) and the build's scratch
//! (transient: a deep capture's lists, the volume's voxelisation), both alike. Byte budgets
//! compare resident bytes; the transient part is reported apart, never left out. A technique
//! given a memory limit ([`MemoryBudget::limited`], a sweep cell's byte budget) sizes the
//! scratch it can shed to what the limit leaves ([`MemoryLedger::remaining_bytes`]): the deep
//! capture its bands, the volume its slabs.
//!
//! The ledger is also where allocations are refused *before* they reach the driver: each
//! texture and buffer is checked against the device's limits and against a memory budget
//! ([`MemoryBudget`]), so a configuration that cannot be held is one [`AllocationError`] line,
//! not an out-of-memory panic inside wgpu.

/// Environment variable that sets the memory budget of one technique, in MiB.
pub const BUDGET_ENV: &str = "SMOKESHADOW_MEMORY_BUDGET_MIB";

/// Default budget of one technique's allocations: 4 GiB. wgpu cannot ask a device how much
/// memory it has, so this is a fixed, documented ceiling that every current GPU and lavapipe on
/// a 16 GB machine can hold next to the frame; set [`BUDGET_ENV`] to change it.
pub const DEFAULT_BUDGET_BYTES: u64 = 4 << 30;

/// What one allocation may not exceed: the device's limits and the budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryBudget {
    pub max_texture_dimension_2d: u32,
    pub max_texture_array_layers: u32,
    pub max_buffer_size: u64,
    /// Largest storage binding: a buffer bound as storage is checked against it.
    pub max_storage_binding_bytes: u64,
    /// Total bytes one ledger may hold.
    pub total_bytes: u64,
}

impl MemoryBudget {
    /// The device's limits and the budget from `BUDGET_ENV` (default `DEFAULT_BUDGET_BYTES`).
    pub fn for_device(limits: &wgpu::Limits) -> Self {
        let total_bytes = std::env::var(BUDGET_ENV)
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok())
            .filter(|&mib| mib > 0)
            .map_or(DEFAULT_BUDGET_BYTES, |mib| mib << 20);
        Self {
            max_texture_dimension_2d: limits.max_texture_dimension_2d,
            max_texture_array_layers: limits.max_texture_array_layers,
            max_buffer_size: limits.max_buffer_size,
            max_storage_binding_bytes: limits.max_storage_buffer_binding_size,
            total_bytes,
        }
    }

    /// [`MemoryBudget::for_device`] with its total lowered to `limit_bytes` where one is given
    /// (a byte budget's memory: what a technique may hold, scratch included).
    pub fn limited(limits: &wgpu::Limits, limit_bytes: Option<u64>) -> Self {
        let mut budget = Self::for_device(limits);
        if let Some(limit) = limit_bytes {
            budget.total_bytes = budget.total_bytes.min(limit);
        }
        budget
    }

    /// No limit at all (unit tests of the accounting).
    pub fn unlimited() -> Self {
        Self {
            max_texture_dimension_2d: u32::MAX,
            max_texture_array_layers: u32::MAX,
            max_buffer_size: u64::MAX,
            max_storage_binding_bytes: u64::MAX,
            total_bytes: u64::MAX,
        }
    }
}

/// An allocation refused before it was made. Renders as one line naming it and the limit.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AllocationError {
    #[error(
        "{label} would be {width}x{height} texels, but the device allows at most {max}x{max}: \
         use a lower --shadow-res or output size"
    )]
    TextureTooLarge {
        label: String,
        width: u32,
        height: u32,
        max: u32,
    },
    #[error("{label} would have {layers} layers, but the device allows at most {max}")]
    TooManyLayers {
        label: String,
        layers: u32,
        max: u32,
    },
    #[error(
        "{label} would be {bytes} bytes, but the device allows buffers of at most {max} bytes{binding}"
    )]
    BufferTooLarge {
        label: String,
        bytes: u64,
        max: u64,
        /// " (as a storage binding)" when the binding limit is the one exceeded.
        binding: &'static str,
    },
    #[error(
        "{label} ({bytes} bytes) would bring this technique to {total} bytes, over its memory \
         budget of {budget} bytes ({budget_mib} MiB: its byte budget's, or at most \
         SMOKESHADOW_MEMORY_BUDGET_MIB): use fewer channels, a lower --shadow-res or a larger \
         budget"
    )]
    OverBudget {
        label: String,
        bytes: u64,
        total: u64,
        budget: u64,
        budget_mib: u64,
    },
    #[error("{label} could not be filled at creation: {reason}")]
    Mapping { label: String, reason: String },
}

/// One recorded allocation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LedgerEntry {
    pub label: String,
    pub bytes: u64,
    /// Scratch the build needs while it runs but the lookup never reads (a deep capture's
    /// per-texel lists before compression): still allocated and counted, reported apart.
    pub transient: bool,
}

/// A list of labelled allocations and their sizes in bytes, checked against a [`MemoryBudget`].
#[derive(Clone, Debug)]
pub struct MemoryLedger {
    entries: Vec<LedgerEntry>,
    budget: MemoryBudget,
    /// The most [`MemoryLedger::total_bytes`] has been: what was held at once.
    peak: u64,
}

impl MemoryLedger {
    /// An empty ledger that refuses what `budget` does not allow.
    pub fn new(budget: MemoryBudget) -> Self {
        Self {
            entries: Vec::new(),
            budget,
            peak: 0,
        }
    }

    /// An empty ledger for allocations on a device with `limits`.
    pub fn for_device(limits: &wgpu::Limits) -> Self {
        Self::new(MemoryBudget::for_device(limits))
    }

    /// An empty ledger for a technique on a device with `limits`, held to `limit_bytes` (its
    /// byte budget's memory, [`crate::scene::TechniqueParams::memory_limit_bytes`]) where set.
    pub fn for_technique(limits: &wgpu::Limits, limit_bytes: Option<u64>) -> Self {
        Self::new(MemoryBudget::limited(limits, limit_bytes))
    }

    /// Checks a texture against the limits and the budget, then creates and records it.
    pub fn texture(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::TextureDescriptor<'_>,
    ) -> Result<wgpu::Texture, AllocationError> {
        self.texture_as(device, desc, false)
    }

    /// [`MemoryLedger::texture`], recorded as transient (build scratch the lookup never reads).
    pub fn texture_transient(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::TextureDescriptor<'_>,
    ) -> Result<wgpu::Texture, AllocationError> {
        self.texture_as(device, desc, true)
    }

    fn texture_as(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::TextureDescriptor<'_>,
        transient: bool,
    ) -> Result<wgpu::Texture, AllocationError> {
        let label = desc.label.unwrap_or("texture");
        let max = self.budget.max_texture_dimension_2d;
        if desc.size.width > max || desc.size.height > max {
            return Err(AllocationError::TextureTooLarge {
                label: label.to_owned(),
                width: desc.size.width,
                height: desc.size.height,
                max,
            });
        }
        if desc.dimension == wgpu::TextureDimension::D2
            && desc.size.depth_or_array_layers > self.budget.max_texture_array_layers
        {
            return Err(AllocationError::TooManyLayers {
                label: label.to_owned(),
                layers: desc.size.depth_or_array_layers,
                max: self.budget.max_texture_array_layers,
            });
        }
        self.reserve(label, texture_bytes(desc), transient)?;
        Ok(device.create_texture(desc))
    }

    /// Checks a buffer against the limits (the storage-binding limit for storage buffers) and
    /// the budget, then creates and records it.
    pub fn buffer(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::BufferDescriptor<'_>,
    ) -> Result<wgpu::Buffer, AllocationError> {
        self.buffer_as(device, desc, false)
    }

    /// [`MemoryLedger::buffer`], recorded as transient (build scratch the lookup never reads).
    pub fn buffer_transient(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::BufferDescriptor<'_>,
    ) -> Result<wgpu::Buffer, AllocationError> {
        self.buffer_as(device, desc, true)
    }

    fn buffer_as(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::BufferDescriptor<'_>,
        transient: bool,
    ) -> Result<wgpu::Buffer, AllocationError> {
        let label = desc.label.unwrap_or("buffer");
        let storage = desc.usage.contains(wgpu::BufferUsages::STORAGE);
        let (max, binding) =
            if storage && self.budget.max_storage_binding_bytes < self.budget.max_buffer_size {
                (
                    self.budget.max_storage_binding_bytes,
                    " (as a storage binding)",
                )
            } else {
                (self.budget.max_buffer_size, "")
            };
        if desc.size > max {
            return Err(AllocationError::BufferTooLarge {
                label: label.to_owned(),
                bytes: desc.size,
                max,
                binding,
            });
        }
        self.reserve(label, desc.size, transient)?;
        Ok(device.create_buffer(desc))
    }

    /// [`MemoryLedger::buffer`] created with `contents` (its size: the contents' length, padded
    /// to wgpu's copy alignment as `create_buffer_init` pads it).
    pub fn buffer_init(
        &mut self,
        device: &wgpu::Device,
        label: &str,
        contents: &[u8],
        usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, AllocationError> {
        let size = (contents.len() as u64)
            .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT)
            .max(wgpu::COPY_BUFFER_ALIGNMENT);
        let buffer = self.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: true,
            },
        )?;
        let mut view =
            buffer
                .slice(..)
                .get_mapped_range_mut()
                .map_err(|e| AllocationError::Mapping {
                    label: label.to_owned(),
                    reason: e.to_string(),
                })?;
        view.slice(..contents.len()).copy_from_slice(contents);
        drop(view);
        buffer.unmap();
        Ok(buffer)
    }

    /// Records `bytes` under `label` if the budget allows them.
    fn reserve(&mut self, label: &str, bytes: u64, transient: bool) -> Result<(), AllocationError> {
        let total = self.total_bytes().saturating_add(bytes);
        if total > self.budget.total_bytes {
            return Err(AllocationError::OverBudget {
                label: label.to_owned(),
                bytes,
                total,
                budget: self.budget.total_bytes,
                budget_mib: self.budget.total_bytes >> 20,
            });
        }
        self.entries.push(LedgerEntry {
            label: label.to_owned(),
            bytes,
            transient,
        });
        self.peak = self.peak.max(total);
        Ok(())
    }

    /// Forgets the allocation labelled `label` (it was dropped or is about to be replaced).
    pub fn forget(&mut self, label: &str) {
        self.entries.retain(|e| e.label != label);
    }

    /// Total bytes recorded now, transient ones included.
    pub fn total_bytes(&self) -> u64 {
        self.entries.iter().map(|e| e.bytes).sum()
    }

    /// The most bytes recorded at once since the ledger began: the resident bytes a technique
    /// is charged (a list that grew was held beside nothing else, since its old buffer is
    /// forgotten before the new one is reserved, so this is the largest configuration held).
    pub fn peak_bytes(&self) -> u64 {
        self.peak.max(self.total_bytes())
    }

    /// Bytes the budget still allows: what scratch that can shed may take.
    pub fn remaining_bytes(&self) -> u64 {
        self.budget.total_bytes.saturating_sub(self.total_bytes())
    }

    /// The part of [`MemoryLedger::total_bytes`] recorded as transient: build scratch the
    /// lookup never reads (a deep capture's uncompressed lists).
    pub fn transient_bytes(&self) -> u64 {
        self.entries
            .iter()
            .filter(|e| e.transient)
            .map(|e| e.bytes)
            .sum()
    }

    /// The recorded allocations, in creation order.
    pub fn entries(&self) -> &[LedgerEntry] {
        &self.entries
    }
}

/// The largest `n` in `range` for which `fits(n)` holds, `fits` true up to some `n` and false
/// beyond (bytes that grow with `n`): how scratch that can shed sizes itself to what a memory
/// limit leaves. `None` when not even the range's first fits.
pub fn largest_that_fits(
    range: std::ops::RangeInclusive<u32>,
    fits: impl Fn(u32) -> bool,
) -> Option<u32> {
    let (mut lo, mut hi) = range.into_inner();
    if lo > hi || !fits(lo) {
        return None;
    }
    while lo < hi {
        let mid = lo + (hi - lo).div_ceil(2);
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    Some(lo)
}

/// Bytes of a texture as described (all mips and layers; block-compressed formats included).
pub fn texture_bytes(desc: &wgpu::TextureDescriptor<'_>) -> u64 {
    let block = u64::from(
        desc.format
            .block_copy_size(None)
            .expect("colour formats without aspects have a block size"),
    );
    let (bw, bh) = desc.format.block_dimensions();
    let layers = u64::from(desc.size.depth_or_array_layers);
    (0..desc.mip_level_count)
        .map(|mip| {
            let w = (desc.size.width >> mip).max(1).div_ceil(bw);
            let h = (desc.size.height >> mip).max(1).div_ceil(bh);
            u64::from(w) * u64::from(h) * block * layers
        })
        .sum()
}

/// Bytes as a short human figure (binary units: 12.0 MiB).
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut value = n as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_bytes_counts_texels_layers_and_format() {
        let desc = wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: 512,
                height: 512,
                depth_or_array_layers: 3,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        };
        assert_eq!(texture_bytes(&desc), 512 * 512 * 3 * 8);
        let r16 = wgpu::TextureDescriptor {
            format: wgpu::TextureFormat::R16Float,
            ..desc
        };
        assert_eq!(texture_bytes(&r16), 512 * 512 * 3 * 2);
    }

    #[test]
    fn transient_bytes_are_part_of_the_total_and_reported_apart() {
        let mut ledger = MemoryLedger::new(MemoryBudget::unlimited());
        ledger.reserve("kept", 100, false).unwrap();
        ledger.reserve("scratch", 40, true).unwrap();
        ledger.reserve("more scratch", 2, true).unwrap();
        assert_eq!((ledger.total_bytes(), ledger.transient_bytes()), (142, 42));
        ledger.forget("scratch");
        assert_eq!((ledger.total_bytes(), ledger.transient_bytes()), (102, 2));
        // What was held at once is what is charged.
        assert_eq!(ledger.peak_bytes(), 142);
        ledger.reserve("regrown scratch", 20, true).unwrap();
        assert_eq!((ledger.total_bytes(), ledger.peak_bytes()), (122, 142));
    }

    #[test]
    fn the_largest_that_fits_is_found_at_either_end_and_between() {
        assert_eq!(largest_that_fits(1..=100, |n| n <= 37), Some(37));
        assert_eq!(largest_that_fits(1..=100, |_| true), Some(100));
        assert_eq!(largest_that_fits(1..=100, |n| n <= 1), Some(1));
        assert_eq!(largest_that_fits(1..=100, |_| false), None);
        assert_eq!(largest_that_fits(0..=u32::MAX, |n| n <= 5), Some(5));
    }

    #[test]
    fn a_limited_ledger_refuses_past_its_limit_and_says_what_is_left() {
        let budget = MemoryBudget {
            total_bytes: 1000,
            ..MemoryBudget::unlimited()
        };
        let mut ledger = MemoryLedger::new(budget);
        ledger.reserve("a", 600, false).unwrap();
        assert_eq!(ledger.remaining_bytes(), 400);
        let err = ledger.reserve("b", 401, true).unwrap_err();
        assert!(
            matches!(
                err,
                AllocationError::OverBudget {
                    total: 1001,
                    budget: 1000,
                    ..
                }
            ),
            "{err}"
        );
        ledger.reserve("b", 400, true).unwrap();
        assert_eq!((ledger.remaining_bytes(), ledger.peak_bytes()), (0, 1000));
    }
}
