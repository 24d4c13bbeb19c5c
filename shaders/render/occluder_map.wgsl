// The occluders' depth map: the opaque geometry rasterised from the light (its back faces: the
// pipeline culls the faces turned towards the light), each texel keeping the radial distance
// from the light over the map's far distance. Read by common/occluders_map.wgsl.
#import common/frame.wgsl
#import common/opaque_vertex.wgsl

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
};

@vertex
fn vs_main(v: OpaqueVertex) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.occluder_clip_from_world * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @builtin(frag_depth) f32 {
    return min(distance(in.world, frame.light_pos.xyz) * frame.occluders.y, 1.0);
}
