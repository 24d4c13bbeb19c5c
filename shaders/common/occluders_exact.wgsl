// Visibility of the light through the opaque geometry, exactly: the segment from the point to
// the light is tested against every box (slab test) and the ground square. 0 where it hits one,
// else 1: the reference `exact` treats an opaque hit as T = 0. (The other techniques read the
// filtered depth map of common/occluders_map.wgsl; both define `occluder_visibility`.)
#import common/lighting.wgsl

struct OccluderBox {
    min: vec4<f32>,
    max: vec4<f32>,
};

@group(0) @binding(3) var<storage, read> occluder_boxes: array<OccluderBox>;

// Hits this close to the point itself do not count, nor does the ground for a point this close
// to its plane: `frame.ground.z`, a length that follows the scene's scale (src/frame/occluders.rs,
// `epsilon_m`: 1e-4 of the farthest smoke's distance from the light, and never under 32 float
// steps of the light's coordinates). A point on a lit face, whose segment leaves its box at once,
// and a point on the ground, whose interpolated height rounds to either side of the plane, are
// then never shadowed by their own surface; `shadow::closed_form::occluder_visibility` mirrors it.
fn occluder_visibility(p: vec3<f32>) -> f32 {
    let epsilon_m = frame.ground.z;
    let to_light = frame.light_pos.xyz - p;
    let length_m = length(to_light);
    let t_min = epsilon_m / max(length_m, 1e-30);
    // The ground square at y = height: it occludes where the segment crosses its plane inside
    // the square (the point and the light on opposite sides).
    let below = p.y - frame.ground.x;
    let light_above = frame.light_pos.y - frame.ground.x;
    if abs(below) > epsilon_m && below * light_above < 0.0 {
        let q = p + to_light * (below / (below - light_above));
        if all(abs(q.xz) <= vec2<f32>(frame.ground.y)) {
            return 0.0;
        }
    }
    // Zero components become tiny ones of either sign: their slabs then span (-inf, inf) or
    // nothing, as the limit says.
    let d = select(to_light, vec3<f32>(1e-20), abs(to_light) < vec3<f32>(1e-20));
    let inv = 1.0 / d;
    let count = u32(frame.occluders.w);
    for (var i = 0u; i < count; i++) {
        let b = occluder_boxes[i];
        let t0 = (b.min.xyz - p) * inv;
        let t1 = (b.max.xyz - p) * inv;
        let near = min(t0, t1);
        let far = max(t0, t1);
        let enter = max(max(near.x, near.y), near.z);
        let exit = min(min(far.x, far.y), far.z);
        if exit >= max(enter, t_min) && enter <= 1.0 {
            return 0.0;
        }
    }
    return 1.0;
}
