// Shows one channel of a shadow map as an image (the viewer's inspector). Optical depths are
// drawn as the opacity they stand for, 1 - exp(-Ω); normalised depths as they are; signed
// values (Fourier coefficients) as 1 - exp(-|v|) tinted blue when positive, red when negative.
// Keep `MapViewParams` in sync with src/viewer/map_view.rs.

struct MapViewParams {
    component: u32,
    // 0: optical depth, 1: normalised depth in [0, 1], 2: signed.
    kind: u32,
    // Multiplies the value before mapping (exposure of the inspector).
    scale: f32,
    _pad: u32,
};

@group(0) @binding(0) var map: texture_2d<f32>;
@group(0) @binding(1) var<uniform> view: MapViewParams;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VertexOut {
    // One triangle covering the target.
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    var out: VertexOut;
    out.clip = vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
    out.uv = vec2<f32>(uv.x, 1.0 - uv.y);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let dims = vec2<f32>(textureDimensions(map));
    let texel = vec2<i32>(clamp(in.uv * dims, vec2<f32>(0.0), dims - vec2<f32>(1.0)));
    let v = textureLoad(map, texel, 0)[view.component] * view.scale;
    switch view.kind {
        case 1u: {
            return vec4<f32>(vec3<f32>(clamp(v, 0.0, 1.0)), 1.0);
        }
        case 2u: {
            let a = 1.0 - exp(-abs(v));
            return vec4<f32>(select(vec3<f32>(0.25, 0.5, 1.0), vec3<f32>(1.0, 0.35, 0.25), v < 0.0) * a, 1.0);
        }
        default: {
            return vec4<f32>(vec3<f32>(1.0 - exp(-max(v, 0.0))), 1.0);
        }
    }
}
