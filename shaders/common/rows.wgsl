// A linear array held as a texture's rows (ROW_TEXELS in src/gpu/mod.rs): element i at texel
// (i % 2^ROW_BITS, i / 2^ROW_BITS). llvmpipe fetches a texture's texels for the lanes of a SIMD
// group in one gather, where it loads a storage buffer's words lane by lane.

const ROW_BITS: u32 = 12u;

fn row_texel(i: u32) -> vec2<u32> {
    return vec2<u32>(i & ((1u << ROW_BITS) - 1u), i >> ROW_BITS);
}
