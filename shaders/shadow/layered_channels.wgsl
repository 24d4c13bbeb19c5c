// Every packed channel of a layered map at once, for the lookups that weigh them all (`fom`,
// `msm`, `tmsm`). Written out target by target over the LAYERED_TARGETS the budget packs, a
// constant composed before the lookup (src/shadow/layered.rs, `lookup_constants`), so that a
// lookup that also indexes the channels by constants keeps them in registers (llvmpipe keeps a
// private array indexed at run time in memory).
#import shadow/layered.wgsl

// Every packed channel, bilinearly filtered (channels beyond `packed` in the last target are 0).
fn layered_channels(uv: vec2<f32>) -> array<f32, 32> {
    var c: array<f32, 32>;
    #unroll t 0..LAYERED_TARGETS
        let v = layered_target(t, uv);
        c[4u * t] = v.x;
        c[4u * t + 1u] = v.y;
        c[4u * t + 2u] = v.z;
        c[4u * t + 3u] = v.w;
    #end_unroll
    return c;
}
