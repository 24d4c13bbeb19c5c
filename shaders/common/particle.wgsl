// Particle instances, billboards facing an eye point, and the spherical-particle density model
// (thesis 3.2.2.3, Umenhoffer et al. 2006): a particle is a sphere of radius r whose extinction
// along a ray at distance d from its centre is τ(1 - d/r), constant along the chord.

// Keep in sync with `ParticleInstance` in src/render/gpu_data.rs.
struct ParticleIn {
    // xyz: centre (m); w: radius (m).
    @location(0) center_radius: vec4<f32>,
    // rgb: albedo; a: extinction τ (1/m).
    @location(1) albedo_density: vec4<f32>,
};

// Vertices per billboard: one quad as two triangles. (A software rasteriser pays per triangle
// edge crossing its 4x4 pixel blocks, so finer fans around the disc cost more than the square's
// extra corners save.)
const BILLBOARD_VERTICES: u32 = 6u;

// Corner of the quad for vertex `index`, in [-1, 1]².
fn quad_corner(index: u32) -> vec2<f32> {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    return corners[index % 6u];
}

// Unit vectors spanning the plane through a billboard's centre perpendicular to the eye.
struct BillboardFrame {
    right: vec3<f32>,
    up: vec3<f32>,
    // Factor by which the quad exceeds the radius so that it covers the sphere's silhouette.
    grow: f32,
};

// World position of a billboard corner: a quad through the sphere centre, perpendicular to the
// direction from `eye`, enlarged so that it covers the sphere's silhouette seen from `eye` under
// perspective (a quad of half-size r would clip it).
fn billboard_frame(center: vec3<f32>, radius: f32, eye: vec3<f32>) -> BillboardFrame {
    var out: BillboardFrame;
    let to_center = center - eye;
    let dist = max(length(to_center), 1e-4);
    let forward = to_center / dist;
    var helper = vec3<f32>(0.0, 1.0, 0.0);
    if abs(forward.y) > 0.99 {
        helper = vec3<f32>(1.0, 0.0, 0.0);
    }
    out.right = normalize(cross(forward, helper));
    out.up = cross(out.right, forward);
    // Silhouette half-size at the centre plane: r·D/sqrt(D² - r²); capped when the eye is
    // (nearly) inside the sphere, where the quad then covers the view generously.
    out.grow = select(8.0, min(dist / sqrt(max(dist * dist - radius * radius, 1e-8)), 8.0), dist > radius * 1.01);
    return out;
}

fn billboard_corner(center: vec3<f32>, radius: f32, frame: BillboardFrame, corner: vec2<f32>) -> vec3<f32> {
    return center + (frame.right * corner.x + frame.up * corner.y) * (radius * frame.grow);
}

// The chord of a ray through a sphere.
struct Chord {
    // Distance along the ray to the chord midpoint (closest approach to the centre).
    t_mid: f32,
    // Half-length of the chord, w = sqrt(r² - d²) (0 when the ray misses).
    half_width: f32,
    // Distance from the ray to the centre, d.
    d: f32,
};

fn sphere_chord(origin: vec3<f32>, dir: vec3<f32>, center: vec3<f32>, radius: f32) -> Chord {
    var out: Chord;
    let oc = center - origin;
    out.t_mid = dot(oc, dir);
    let d2 = max(dot(oc, oc) - out.t_mid * out.t_mid, 0.0);
    out.d = sqrt(d2);
    out.half_width = sqrt(max(radius * radius - d2, 0.0));
    return out;
}

// Extinction along a ray at distance d from the centre: τ(1 - d/r).
fn chord_extinction(tau: f32, d: f32, radius: f32) -> f32 {
    return tau * max(1.0 - d / radius, 0.0);
}
