// Opaque pass: the ground and the boxes, lit by the spotlight and shadowed by the smoke through
// the active technique's `shadow_transmittance` and by the opaque geometry through
// `occluder_visibility`.
#import common/lighting.wgsl
#import shadow_technique
#import occluders
#import common/opaque_vertex.wgsl

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) albedo: vec3<f32>,
};

@vertex
fn vs_main(v: OpaqueVertex) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.clip_from_world * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.albedo = v.albedo;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // A point light draws the geometry once per cube face, each fragment in its own face's pass.
    if !in_light_face(in.world) {
        discard;
    }
    let n = normalize(in.normal);
    let to_light = normalize(frame.light_pos.xyz - in.world);
    let lambert = max(dot(n, to_light), 0.0);
    var direct = vec3<f32>(0.0);
    let irradiance = spot_irradiance(in.world) * lambert;
    // Only where the spotlight reaches does the smoke's shadow matter: outside its cone (or on
    // faces turned away) the lookup is skipped, not multiplied by zero.
    if any(irradiance > vec3<f32>(0.0)) {
        let visibility = occluder_visibility(in.world);
        if visibility > 0.0 {
            direct = irradiance * (visibility * shadow_transmittance(in.world));
        }
    }
    let radiance = in.albedo * (direct / PI + frame.ambient.rgb);
    // Alpha 0: the HDR target's alpha channel accumulates smoke opacity only.
    return vec4<f32>(radiance, 0.0);
}
