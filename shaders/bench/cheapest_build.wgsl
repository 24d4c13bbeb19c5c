// The bench's cheapest possible build (src/bench/bound.rs): the light-facing billboards every
// map-building technique draws, each fragment adding the optical depth of its light ray through
// the particle, τ(1 - d/r)·2w, to one half-float channel with additive blending. A build that
// knows less than this does not know where the smoke is; every technique's build does at least
// this per fragment, so its time is the floor the techniques' builds are measured against.
#import shadow/layered_build.wgsl

@fragment
fn fs_cheapest(in: BuildVertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(splat_fragment(in, false).optical_depth);
}
