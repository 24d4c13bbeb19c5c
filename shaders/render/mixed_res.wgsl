// Mixed-resolution particles (issue 14 §3; Jansen & Bavoil 2011, NVIDIA's smokeParticles, the
// low-resolution rendering with bilateral upsampling of Yusov's slides): the particle pass draws
// into a premultiplied HDR target of 1/D the frame's size per axis, against a downsampled opaque
// depth (`fs_downsample`), and `fs_upsample` composites it over the full-resolution frame,
// choosing per full-resolution pixel the low-resolution texels that saw the same surface.
// src/render/mixed_res.rs builds the passes.
#import common/frame.wgsl

// Keep in sync with `MixedResUniforms` in src/render/mixed_res.rs.
struct MixedRes {
    // Full-resolution pixels per low-resolution texel along each axis (2 or 4).
    divisor: u32,
    // Relative difference of view depth under which a low-resolution texel counts as seeing
    // the pixel's surface.
    depth_tolerance: f32,
    pad0: u32,
    pad1: u32,
};

@group(1) @binding(0) var full_depth: texture_depth_2d;
@group(1) @binding(1) var low_depth: texture_depth_2d;
@group(1) @binding(2) var low_color: texture_2d<f32>;
@group(1) @binding(3) var<uniform> mixed: MixedRes;

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the target.
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// The low-resolution depth: the NEAREST opaque depth of the D x D block. The spherical
// billboards clip each chord at the opaque surface, Δs = min(Zs, |B|) - max(near, |F|), so a
// texel holds exactly the smoke in front of the one depth it was clipped at, and the upsample
// can only hand each pixel the smoke of a texel whose depth matches its own. Every pixel's own
// texel is in its 2x2 upsample footprint; with the nearest depth, the pixels of the nearest
// surface in a block (the box along its silhouette) always find it there, clipped at their own
// depth: the occluder's edge gets exactly its own smoke, never the smoke behind it, and stays
// as sharp as the opaque pass drew it. The farther pixels of a mixed block (the ground beside
// the box) take their smoke from a neighbouring texel that lies wholly behind the edge. With
// the farthest depth it would be the other way round, and worse: the mixed texel would hold
// the smoke behind the box, and a box pixel whose footprint leans away from the box's interior
// finds no texel clipped at the box, so a band of smoke from behind would bleed over the edge.
@fragment
fn fs_downsample(@builtin(position) pos: vec4<f32>) -> @builtin(frag_depth) f32 {
    let size = vec2<i32>(textureDimensions(full_depth));
    let n = i32(mixed.divisor);
    let base = vec2<i32>(pos.xy) * n;
    var nearest = 1.0;
    for (var y = 0; y < n; y++) {
        for (var x = 0; x < n; x++) {
            let p = min(base + vec2<i32>(x, y), size - vec2<i32>(1));
            nearest = min(nearest, textureLoad(full_depth, p, 0));
        }
    }
    return nearest;
}

// View-space distance along the camera axis of a perspective depth (0 at near, 1 at far: the
// background, where no opaque surface is, counts as the far plane).
fn view_z(depth: f32) -> f32 {
    let near = frame.camera_pos.w;
    let far = frame.camera_forward.w;
    return near * far / (far - depth * (far - near));
}

// Depth-aware (bilateral) upsample: the four low-resolution texels around the pixel, weighted
// bilinearly, but only those whose depth is within `depth_tolerance` of the pixel's own (a step
// kernel in depth); when none is, the nearest-depth texel alone (Bavoil's nearest-depth
// upsampling). Where the smoke lies over one surface this is plain bilinear filtering; at an
// opaque silhouette each pixel takes only texels of its own surface, so the edge stays as sharp
// as the opaque pass drew it.
// One texel's part in the upsample: its bilinear weight `w` if its depth is within the
// tolerance of the pixel's view depth `z`, else 0; and its depth difference, for the fallback.
fn depth_weight(texel: vec2<i32>, w: f32, z: f32) -> vec2<f32> {
    let diff = abs(view_z(textureLoad(low_depth, texel, 0)) - z);
    return vec2<f32>(select(0.0, w, diff <= mixed.depth_tolerance * z), diff);
}

// (Written out for the four texels rather than looped over arrays: a software rasteriser
// keeps a private array per SIMD lane in memory, which cost more than the rest of the pass.)
@fragment
fn fs_upsample(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let low_max = vec2<i32>(textureDimensions(low_color)) - vec2<i32>(1);
    let uv = pos.xy / f32(mixed.divisor) - vec2<f32>(0.5);
    let corner = vec2<i32>(floor(uv));
    let f = uv - floor(uv);
    let t00 = clamp(corner, vec2<i32>(0), low_max);
    let t11 = clamp(corner + vec2<i32>(1), vec2<i32>(0), low_max);
    let t10 = vec2<i32>(t11.x, t00.y);
    let t01 = vec2<i32>(t00.x, t11.y);
    let c00 = textureLoad(low_color, t00, 0);
    let c10 = textureLoad(low_color, t10, 0);
    let c01 = textureLoad(low_color, t01, 0);
    let c11 = textureLoad(low_color, t11, 0);
    // No smoke around this pixel (most of the frame): "over" nothing leaves it as it is, and
    // discarding skips the depth reads and the blend.
    if c00.a + c10.a + c01.a + c11.a <= 0.0 {
        discard;
    }
    let z = view_z(textureLoad(full_depth, vec2<i32>(pos.xy), 0));
    let w00 = depth_weight(t00, (1.0 - f.x) * (1.0 - f.y), z);
    let w10 = depth_weight(t10, f.x * (1.0 - f.y), z);
    let w01 = depth_weight(t01, (1.0 - f.x) * f.y, z);
    let w11 = depth_weight(t11, f.x * f.y, z);
    let weight = w00.x + w10.x + w01.x + w11.x;
    if weight > 1.0e-4 {
        return (w00.x * c00 + w10.x * c10 + w01.x * c01 + w11.x * c11) / weight;
    }
    // Nearest depth (ties: the first in this order).
    var nearest = c00;
    var nearest_diff = w00.y;
    if w10.y < nearest_diff {
        nearest = c10;
        nearest_diff = w10.y;
    }
    if w01.y < nearest_diff {
        nearest = c01;
        nearest_diff = w01.y;
    }
    if w11.y < nearest_diff {
        nearest = c11;
    }
    return nearest;
}
