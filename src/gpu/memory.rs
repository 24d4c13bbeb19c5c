//! Memory accounting from what is actually allocated.
//!
//! Every texture and buffer a shadow technique owns is created through a [`MemoryLedger`], which
//! records its size computed from the descriptor wgpu received (format block size x extent x
//! layers x mips, or the buffer size). The bytes a technique reports are the ledger's sum, so the
//! number cannot drift from the allocations.

/// A list of labelled allocations and their sizes in bytes.
#[derive(Clone, Debug, Default)]
pub struct MemoryLedger {
    entries: Vec<(String, u64)>,
}

impl MemoryLedger {
    /// Creates a texture and records its size.
    pub fn texture(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::TextureDescriptor<'_>,
    ) -> wgpu::Texture {
        let bytes = texture_bytes(desc);
        self.entries
            .push((desc.label.unwrap_or("texture").to_owned(), bytes));
        device.create_texture(desc)
    }

    /// Creates a buffer and records its size.
    pub fn buffer(
        &mut self,
        device: &wgpu::Device,
        desc: &wgpu::BufferDescriptor<'_>,
    ) -> wgpu::Buffer {
        self.entries
            .push((desc.label.unwrap_or("buffer").to_owned(), desc.size));
        device.create_buffer(desc)
    }

    /// Records an allocation made elsewhere, by the size of the buffer(s) actually created.
    pub fn record(&mut self, label: &str, bytes: u64) {
        self.entries.push((label.to_owned(), bytes));
    }

    /// Forgets the allocation labelled `label` (it was dropped or is about to be replaced).
    pub fn forget(&mut self, label: &str) {
        self.entries.retain(|(l, _)| l != label);
    }

    /// Total bytes recorded.
    pub fn total_bytes(&self) -> u64 {
        self.entries.iter().map(|(_, b)| b).sum()
    }

    /// The recorded allocations, in creation order.
    pub fn entries(&self) -> &[(String, u64)] {
        &self.entries
    }
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
}
