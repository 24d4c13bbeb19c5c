// `srm` lookup: secondary ray marching (src/shadow/srm.rs): `srm.steps` midpoint samples of the
// density volume from the light to p, over the part of the segment the grid covers.
#import common/medium.wgsl

// Keep in sync with `SrmParams` in src/shadow/srm.rs.
struct SrmParams {
    steps: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
};

@group(1) @binding(0) var<uniform> srm: SrmParams;

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    return exp(-medium_optical_depth(frame.light_pos.xyz, p, srm.steps));
}
