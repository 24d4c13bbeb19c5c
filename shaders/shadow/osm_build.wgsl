// `osm` build: each fragment adds its optical depth to every slice boundary at or beyond its
// depth (additive blending, so no sort); a segment splat adds the part of its chord in front of
// the boundary.
#import shadow/layered_build.wgsl
#import shadow/osm.wgsl

// Values for render target `index`: boundaries k = 4·index + 1 ..= 4·index + 4 at depths k/B
// (0 for boundaries beyond the last slice).
fn prepare_values(splat: Splat, pixel: vec2<f32>) -> Splat {
    return splat;
}

fn target_values(splat: Splat, index: u32) -> vec4<f32> {
    let k = vec4<f32>(f32(index * 4u + 1u)) + vec4<f32>(0.0, 1.0, 2.0, 3.0);
    let b = f32(layered.count);
    return splat.optical_depth * covered_fraction(splat, k / b) * step(k, vec4<f32>(b));
}

//{{BUILD_OUTPUTS}}
