// Visibility of the light through the opaque geometry (ground and boxes), from the occluders'
// depth map: the radial distance from the light to the nearest opaque back face per texel
// (render/occluder_map.wgsl), compared with the point's own distance and filtered over 3x3
// bilinear comparison taps (percentage-closer filtering, Reeves et al. 1987): a 4x4-texel
// penumbra, smooth across texels. Every technique but `exact` multiplies its T(p) by this;
// `exact` tests the boxes analytically (common/occluders_exact.wgsl).
#import common/lighting.wgsl

@group(0) @binding(1) var occluder_map: texture_depth_2d;
@group(0) @binding(2) var occluder_sampler: sampler_comparison;

// The map holds back faces (the faces turned away from the light), so a lit face is compared
// against the far side of its own box, never against itself; the bias only has to cover the
// filter's reach along grazing back faces: one and a half texels' width at the point's distance.
fn occluder_visibility(p: vec3<f32>) -> f32 {
    // Without boxes, and with the light above the ground, the map is empty (the ground's face
    // is turned towards the light): skip the taps.
    if frame.occluders.w == 0.0 && frame.light_pos.y >= frame.ground.x {
        return 1.0;
    }
    // The occluders' map frames the whole cone (the smoke's maps may be fitted to the smoke).
    let clip = frame.occluder_clip_from_world * vec4<f32>(p, 1.0);
    if clip.w <= 1e-6 {
        return 1.0;
    }
    let ndc = clip.xy / clip.w;
    if any(abs(ndc) > vec2<f32>(1.0, 1.0)) {
        return 1.0;
    }
    let map_uv = ndc * vec2<f32>(0.5, -0.5) + vec2<f32>(0.5, 0.5);
    let dist_m = distance(p, frame.light_pos.xyz);
    let side = frame.occluders.z;
    let texel_m = 2.0 * dist_m * (1.0 / side) / max(frame.occluder_clip_from_world[1][1], 1e-6);
    let reference = (dist_m - 1.5 * texel_m) * frame.occluders.y;
    let texel_uv = 1.0 / side;
    var lit = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let uv = map_uv + vec2<f32>(f32(dx), f32(dy)) * texel_uv;
            lit += textureSampleCompareLevel(occluder_map, occluder_sampler, uv, reference);
        }
    }
    return lit * (1.0 / 9.0);
}
