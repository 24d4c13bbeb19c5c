// Spotlight, phase function and the light-space mapping every shadow technique uses.
#import common/frame.wgsl

const PI: f32 = 3.14159265358979;

// Irradiance (W/m²-like) from the spotlight arriving at `p`, before any shadowing: intensity over
// distance squared, times a smooth cone falloff over the penumbra.
fn spot_irradiance(p: vec3<f32>) -> vec3<f32> {
    let to_p = p - frame.light_pos.xyz;
    let dist2 = max(dot(to_p, to_p), 1e-6);
    let cos_angle = dot(to_p * inverseSqrt(dist2), frame.light_dir.xyz);
    let cone = smoothstep(frame.light_pos.w, frame.light_dir.w, cos_angle);
    return frame.light_radiance.rgb * (cone / dist2);
}

// The cube face a direction from a point light falls in: its dominant axis (ties to x, then y),
// 0..6 for +x, -x, +y, -y, +z, -z. Keep in sync with `cube_face` in src/shadow/light_space.rs.
fn cube_face(d: vec3<f32>) -> u32 {
    let a = abs(d);
    if a.x >= a.y && a.x >= a.z {
        return select(1u, 0u, d.x >= 0.0);
    }
    if a.y >= a.z {
        return select(3u, 2u, d.y >= 0.0);
    }
    return select(5u, 4u, d.z >= 0.0);
}

// Whether this frame's light space lights `p`: always for a spotlight (light_depth.w < 0); for
// a point light, whose maps are built on the six faces of a cube, whether `p` lies in the face
// this pass's light space covers (light_depth.w). Passes that light points run once per face
// and keep only their face's points.
fn in_light_face(p: vec3<f32>) -> bool {
    let face = frame.light_depth.w;
    if face < 0.0 {
        return true;
    }
    return f32(cube_face(p - frame.light_pos.xyz)) == face;
}

// Henyey-Greenstein phase function times 4π (so an isotropic medium gives 1), for the angle
// between the light's propagation direction and the direction towards the eye.
fn hg_phase_4pi(cos_theta: f32, g: f32) -> f32 {
    let g2 = g * g;
    let denom = max(1.0 + g2 - 2.0 * g * cos_theta, 1e-4);
    return (1.0 - g2) / (denom * sqrt(denom));
}

// Where a world point lands in the light's shadow map.
struct LightCoords {
    // Shadow-map texture coordinates in [0, 1]².
    uv: vec2<f32>,
    // Radial distance from the light normalised to the frame's smoke bounds: 0 at near, 1 at far.
    depth01: f32,
    // Radial distance from the light in metres.
    dist_m: f32,
    // False outside the light frustum (the spotlight does not reach there anyway).
    inside: bool,
};

fn light_coords(p: vec3<f32>) -> LightCoords {
    var out: LightCoords;
    let clip = frame.light_clip_from_world * vec4<f32>(p, 1.0);
    out.dist_m = distance(p, frame.light_pos.xyz);
    out.depth01 = (out.dist_m - frame.light_depth.x) * frame.light_depth.z;
    if clip.w <= 1e-6 {
        out.inside = false;
        return out;
    }
    let ndc = clip.xy / clip.w;
    out.uv = ndc * vec2<f32>(0.5, -0.5) + vec2<f32>(0.5, 0.5);
    out.inside = all(abs(ndc) <= vec2<f32>(1.0, 1.0));
    return out;
}

// The four texels around `uv` in a `dims`-sized map (clamped to the edge) and their bilinear
// weights, for lookups that must evaluate each texel's own function before blending (a texel's
// visibility is not linear in its stored values).
struct BilinearTaps {
    texels: array<vec2<i32>, 4>,
    weights: vec4<f32>,
};

fn bilinear_taps(uv: vec2<f32>, dims: vec2<i32>) -> BilinearTaps {
    var out: BilinearTaps;
    let f = uv * vec2<f32>(dims) - vec2<f32>(0.5);
    let base = vec2<i32>(floor(f));
    let t = f - floor(f);
    let hi = dims - vec2<i32>(1);
    out.texels[0] = clamp(base, vec2<i32>(0), hi);
    out.texels[1] = clamp(base + vec2<i32>(1, 0), vec2<i32>(0), hi);
    out.texels[2] = clamp(base + vec2<i32>(0, 1), vec2<i32>(0), hi);
    out.texels[3] = clamp(base + vec2<i32>(1, 1), vec2<i32>(0), hi);
    out.weights = vec4<f32>((1.0 - t.x) * (1.0 - t.y), t.x * (1.0 - t.y), (1.0 - t.x) * t.y, t.x * t.y);
    return out;
}
