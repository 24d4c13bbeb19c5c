//! The spotlight's view of the smoke, shared by every technique.
//!
//! The shadow map is a square perspective projection from the light: fitted to the smoke's
//! light-space bounds within the cone ([`Framing::Fit`], the default: the particles' spheres and
//! a density volume's box, re-aimed at their middle, 2% wider), or covering the whole cone
//! ([`Framing::Cone`], the thesis' framing). The opaque occluders' map always covers the cone
//! ([`LightSpace::cone_view_from_world`]): the boxes cast shadows wherever the light reaches. The
//! depth coordinate is the *radial distance from the light*, so each shadow-map texel's light
//! ray crosses a particle along an exact chord and the slices/layers are concentric shells; it is
//! fitted tightly to the particles every frame (nearest sphere surface to farthest), as the
//! thesis' opacity maps require.
//!
//! A point light has six light spaces, the faces of a cube around it ([`LightSpace::faces`]):
//! each a 90° perspective (widened by [`CUBE_FACE_MARGIN`] so that filtered lookups at a face's
//! edge read texels of that face) along one axis direction, all sharing the same radial bounds,
//! so the slices of a layered map are the same spherical shells on every face. A point belongs
//! to the face of its dominant axis ([`cube_face`], mirrored by `cube_face` in
//! shaders/common/lighting.wgsl).

use glam::{Mat4, Vec3};

use crate::scene::{Framing, LightKind, Spotlight};
use crate::sim::Particle;

/// The light's projection and the frame's depth bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSpace {
    /// The spotlight's position, world metres.
    pub position: Vec3,
    /// Perspective projection x view of the spotlight covering its cone.
    pub clip_from_world: Mat4,
    /// The view part alone (right-handed: the light looks down −z).
    pub view_from_world: Mat4,
    /// tan of half the projection's field of view: a view-space point (x, y, z) lands at
    /// NDC (x, y) / (−z · tan_half_fov).
    pub tan_half_fov: f32,
    /// Radial distance from the light to the nearest particle surface, metres.
    pub near_m: f32,
    /// Radial distance from the light to the farthest particle surface, metres.
    pub far_m: f32,
    /// The largest particle radius this frame, metres (0 without particles).
    pub max_radius_m: f32,
    /// The mean particle radius and the mean radial distance of the particles from the light,
    /// metres (0 without particles): the typical footprint `exact` sizes its tiles by.
    pub mean_radius_m: f32,
    pub mean_dist_m: f32,
    /// The cube face (0..6: +x, −x, +y, −y, +z, −z) of a point light's light space; `None`
    /// for a spotlight's.
    pub face: Option<u8>,
    /// The view and tan of half the field of view of the whole cone (a cube face's own, for a
    /// point light): the occluders' map's framing, and the shadow maps' under
    /// [`Framing::Cone`].
    pub cone_view_from_world: Mat4,
    pub cone_tan_half_fov: f32,
}

/// How much wider than the smoke's bounds a fitted light space is: 2%, about five texels of a
/// 512² map on each side, so that the bilinear and filtered taps at the smoke's edge read empty
/// texels of the map (and a point outside the map, which every lookup gives T = 1, has no smoke
/// between it and the light).
pub const FIT_MARGIN: f32 = 1.02;

/// tan of half a cube face's field of view: 1 (90°) plus 2%, about five texels of a 512² map
/// on each side, so the bilinear and filtered taps of a point on the face's edge stay inside it.
pub const CUBE_FACE_MARGIN: f32 = 1.02;

/// Names of the cube faces, in [`cube_face`]'s order.
pub const CUBE_FACE_NAMES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];

/// Axis direction and up vector of each cube face.
const CUBE_FACES: [(Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::NEG_Y),
    (Vec3::NEG_X, Vec3::NEG_Y),
    (Vec3::Y, Vec3::Z),
    (Vec3::NEG_Y, Vec3::NEG_Z),
    (Vec3::Z, Vec3::NEG_Y),
    (Vec3::NEG_Z, Vec3::NEG_Y),
];

/// The cube face a direction from a point light falls in: its dominant axis (ties to x, then
/// y), positive or negative. Keep in sync with `cube_face` in shaders/common/lighting.wgsl.
pub fn cube_face(d: Vec3) -> u8 {
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        if d.x >= 0.0 { 0 } else { 1 }
    } else if a.y >= a.z {
        if d.y >= 0.0 { 2 } else { 3 }
    } else if d.z >= 0.0 {
        4
    } else {
        5
    }
}

impl LightSpace {
    /// The light spaces of `light` this frame: the spotlight's one, or a point light's six
    /// cube faces in [`cube_face`]'s order.
    pub fn faces(light: &Spotlight, particles: &[Particle], framing: Framing) -> Vec<Self> {
        Self::faces_with(light, particles, None, framing)
    }

    /// [`LightSpace::faces`] of a scene that also holds a density volume within the world box
    /// `volume` (min, max): the radial bounds, and a fitted frustum, enclose the box too.
    pub fn faces_with(
        light: &Spotlight,
        particles: &[Particle],
        volume: Option<(Vec3, Vec3)>,
        framing: Framing,
    ) -> Vec<Self> {
        let mut faces: Vec<Self> = match light.kind {
            LightKind::Spot => vec![Self::spot(light, particles, volume, framing)],
            LightKind::Point => (0..6)
                .map(|f| Self::fit_face(light, f, particles))
                .collect(),
        };
        if let Some((lo, hi)) = volume {
            let (near, far) = crate::medium::frame::box_distances(light.position, lo, hi);
            for face in &mut faces {
                face.enclose(near, far, particles.is_empty());
            }
        }
        if framing == Framing::Stable {
            for face in &mut faces {
                let (near, far) = stable_depth_range(face.near_m, face.far_m);
                face.enclose(near, far, false);
            }
        }
        faces
    }

    /// Widens the radial bounds to [`near`, `far`] as well (replacing them when there are no
    /// particles), and the projection's planes with them.
    fn enclose(&mut self, near: f32, far: f32, alone: bool) {
        let (old_near, old_far) = match alone {
            true => (f32::INFINITY, 0.0),
            false => (self.near_m, self.far_m),
        };
        let far = far.max(old_far).max(f32::MIN_POSITIVE);
        let near = near.min(old_near).max(1e-4 * far);
        let far = far.max(near * (1.0 + 1e-4));
        let fov = 2.0 * self.tan_half_fov.atan();
        let z_near = (0.5 * near * (0.5 * fov).cos()).max(1e-6 * far);
        let proj = Mat4::perspective_rh(fov, 1.0, z_near, 2.0 * far);
        self.clip_from_world = proj * self.view_from_world;
        self.near_m = near;
        self.far_m = far;
    }

    /// The spotlight's light space covering its whole cone (the point light's faces:
    /// [`LightSpace::faces`]).
    pub fn cone(light: &Spotlight, particles: &[Particle]) -> Self {
        Self::spot(light, particles, None, Framing::Cone)
    }

    /// The spotlight's light space in `framing`, its bounds enclosing `particles` and the box
    /// `volume`.
    fn spot(
        light: &Spotlight,
        particles: &[Particle],
        volume: Option<(Vec3, Vec3)>,
        framing: Framing,
    ) -> Self {
        let axis = (light.target - light.position).normalize();
        let cone_view = look_along(light.position, axis);
        // A small margin so the penumbra edge is inside the map.
        let cone_fov = (2.0 * light.cone_angle_deg.to_radians() * 1.04).min(170f32.to_radians());
        let (view, fov) = match framing {
            Framing::Cone => (cone_view, cone_fov),
            Framing::Fit | Framing::Stable => smoke_fit(
                light.position,
                cone_view,
                cone_fov,
                particles,
                volume,
                framing == Framing::Stable,
            )
            .unwrap_or((cone_view, cone_fov)),
        };
        let mut space = Self::with_view(light.position, view, fov, None, particles);
        space.cone_view_from_world = cone_view;
        space.cone_tan_half_fov = (0.5 * cone_fov).tan();
        space
    }

    /// Cube face `face` of a point light at `light.position`.
    fn fit_face(light: &Spotlight, face: u8, particles: &[Particle]) -> Self {
        let (axis, up) = CUBE_FACES[usize::from(face)];
        let view = Mat4::look_at_rh(light.position, light.position + axis, up);
        let fov = 2.0 * CUBE_FACE_MARGIN.atan();
        Self::with_view(light.position, view, fov, Some(face), particles)
    }

    /// A light space looking through `view` with a square `fov` (radians), its radial bounds
    /// fitted to every particle (the same on every face of a point light).
    fn with_view(
        position: Vec3,
        view: Mat4,
        fov: f32,
        face: Option<u8>,
        particles: &[Particle],
    ) -> Self {
        let (mut near, mut far, mut max_radius) = (f32::INFINITY, 0.0f32, 0.0f32);
        let (mut radius_sum, mut dist_sum) = (0.0f64, 0.0f64);
        for p in particles {
            let dist = p.position.distance(position);
            near = near.min(dist - p.radius_m);
            far = far.max(dist + p.radius_m);
            max_radius = max_radius.max(p.radius_m);
            radius_sum += f64::from(p.radius_m);
            dist_sum += f64::from(dist);
        }
        let count = particles.len().max(1) as f64;
        if !near.is_finite() {
            (near, far) = (1.0, 2.0);
        }
        // Every bound is relative to the smoke's own distance from the light, so that a 1 cm
        // puff and a 1 km cloud are fitted alike: a light inside the smoke starts its depth
        // range at 1e-4 of the farthest surface instead of at 0.
        let far = far.max(f32::MIN_POSITIVE);
        let near = near.max(1e-4 * far);
        let far = far.max(near * (1.0 + 1e-4));
        // The projection only clips what the builds rasterise (their depth is radial, computed
        // in the shaders): no billboard of the smoke may be cut. A light-facing billboard's
        // corners lie at least `near` from the light, and at a view depth of at least
        // near · cos(fov/2) (one at the edge of the field of view); half that is the near plane.
        // They lie within twice the farthest surface (r·√2 beyond a centre), the far plane.
        let z_near = (0.5 * near * (0.5 * fov).cos()).max(1e-6 * far);
        let proj = Mat4::perspective_rh(fov, 1.0, z_near, 2.0 * far);
        Self {
            position,
            clip_from_world: proj * view,
            view_from_world: view,
            tan_half_fov: (0.5 * fov).tan(),
            cone_view_from_world: view,
            cone_tan_half_fov: (0.5 * fov).tan(),
            near_m: near,
            far_m: far,
            max_radius_m: max_radius,
            mean_radius_m: (radius_sum / count) as f32,
            mean_dist_m: (dist_sum / count) as f32,
            face,
        }
    }
}

impl LightSpace {
    /// How many texels of a `res`² map in this light space hold smoke: those whose centre's ray
    /// from the light crosses a particle's sphere (or, with a density volume, its box:
    /// `volume`). The rest of the map holds nothing.
    pub fn texels_covering_smoke(
        &self,
        particles: &[Particle],
        volume: Option<(Vec3, Vec3)>,
        res: u32,
    ) -> u64 {
        let res = res.max(1) as usize;
        let mut covered = vec![false; res * res];
        let world_from_view = self.view_from_world.inverse();
        let t = self.tan_half_fov;
        // The ray through texel (x, y)'s centre, in the light's view.
        let ray = |x: usize, y: usize| {
            let ndc_x = (x as f32 + 0.5) / res as f32 * 2.0 - 1.0;
            let ndc_y = 1.0 - (y as f32 + 0.5) / res as f32 * 2.0;
            Vec3::new(ndc_x * t, ndc_y * t, -1.0).normalize()
        };
        // The texels of the tan-space bounds `b`, clamped to the map.
        let texels = |b: [f32; 4]| {
            let to_x = |v: f32| ((v / t * 0.5 + 0.5) * res as f32).floor();
            let to_y = |v: f32| ((0.5 - v / t * 0.5) * res as f32).floor();
            let clamp = |v: f32| v.clamp(0.0, (res - 1) as f32) as usize;
            (
                clamp(to_x(b[0]))..=clamp(to_x(b[2])),
                clamp(to_y(b[3]))..=clamp(to_y(b[1])),
            )
        };
        for p in particles {
            let c = self.view_from_world.transform_point3(p.position);
            if c.length() <= p.radius_m {
                // Around the light: every texel's ray crosses it.
                return (res * res) as u64;
            }
            // (Not wholly in front of the light, within 80° of its axis: outside this map, a
            // cube face's or a fitted one's.)
            let Some(b) = tan_bounds(Mat4::IDENTITY, &[Particle { position: c, ..*p }], None)
            else {
                continue;
            };
            let (xs, ys) = texels(b);
            for y in ys {
                for x in xs.clone() {
                    let d = ray(x, y);
                    let along = c.dot(d);
                    if along > 0.0 && (c - d * along).length_squared() < p.radius_m * p.radius_m {
                        covered[y * res + x] = true;
                    }
                }
            }
        }
        if let Some((lo, hi)) = volume {
            let o = self.position;
            for (i, c) in covered.iter_mut().enumerate() {
                let d = world_from_view.transform_vector3(ray(i % res, i / res));
                let inv = d.recip();
                let (t0, t1) = ((lo - o) * inv, (hi - o) * inv);
                let near = t0.min(t1).max_element();
                let far = t0.max(t1).min_element();
                *c |= far >= near.max(0.0);
            }
        }
        covered.iter().filter(|&&c| c).count() as u64
    }
}

/// A light's view from `position` down `axis`.
fn look_along(position: Vec3, axis: Vec3) -> Mat4 {
    let helper = if axis.y.abs() > 0.99 {
        Vec3::X
    } else {
        Vec3::Y
    };
    Mat4::look_at_rh(position, position + axis, helper)
}

/// The tan-space bounds (x/−z, y/−z: min x, min y, max x, max y) of what `view` sees of the
/// spheres and the corners of the box; `None` when any of it is not wholly in front of the light
/// (within 80° of the view's axis), where no square frustum holds it.
fn tan_bounds(
    view: Mat4,
    particles: &[Particle],
    volume: Option<(Vec3, Vec3)>,
) -> Option<[f32; 4]> {
    let limit = 80f32.to_radians();
    let mut b = [
        f32::INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NEG_INFINITY,
    ];
    // The sphere's outline in each of the view's xz and yz planes: the angle of its centre from
    // the axis, plus the angle its radius subtends there.
    let mut sphere = |c: Vec3, r: f32| -> Option<()> {
        for (axis, lo, hi) in [(c.x, 0, 2), (c.y, 1, 3)] {
            let planar = axis.hypot(c.z);
            if r >= planar {
                return None;
            }
            let centre = axis.atan2(-c.z);
            let spread = (r / planar).asin();
            let (a0, a1) = (centre - spread, centre + spread);
            if a0 <= -limit || a1 >= limit {
                return None;
            }
            b[lo] = b[lo].min(a0.tan());
            b[hi] = b[hi].max(a1.tan());
        }
        Some(())
    };
    for p in particles {
        sphere(view.transform_point3(p.position), p.radius_m)?;
    }
    if let Some((lo, hi)) = volume {
        for i in 0..8 {
            let corner = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            sphere(view.transform_point3(corner), 0.0)?;
        }
    }
    b[0].is_finite().then_some(b)
}

/// The square frustum (view, field of view) holding the smoke's light-space bounds within the
/// cone's square (`cone_view`, `cone_fov`), re-aimed at their middle and [`FIT_MARGIN`] wider;
/// `None` (keep the cone) when there is no smoke, some of it is not in front of the light, or
/// none of it lies in the cone.
fn smoke_fit(
    position: Vec3,
    cone_view: Mat4,
    cone_fov: f32,
    particles: &[Particle],
    volume: Option<(Vec3, Vec3)>,
    stable: bool,
) -> Option<(Mat4, f32)> {
    let t = (0.5 * cone_fov).tan();
    let [x0, y0, x1, y1] = tan_bounds(cone_view, particles, volume)?;
    let (x0, y0, x1, y1) = (x0.max(-t), y0.max(-t), x1.min(t), y1.min(t));
    if x0 >= x1 || y0 >= y1 {
        return None;
    }
    let (x0, y0, x1, y1) = match stable {
        true => stable_window([x0, y0, x1, y1], t),
        false => (x0, y0, x1, y1),
    };
    // The middle of the bounds, as a world direction, and the rectangle's corners seen from it:
    // a plane through the light maps to a line, so the rectangle's image is the quadrilateral of
    // its corners' images.
    let world_from_cone = cone_view.inverse();
    let towards = |x: f32, y: f32| world_from_cone.transform_vector3(Vec3::new(x, y, -1.0));
    let axis = towards(0.5 * (x0 + x1), 0.5 * (y0 + y1)).normalize();
    let view = look_along(position, axis);
    let mut half = 0.0f32;
    for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
        let v = view.transform_vector3(towards(x, y));
        if v.z >= -1e-6 {
            return None;
        }
        half = half.max(v.x.abs().max(v.y.abs()) / -v.z);
    }
    // A stable window has its margin already (and its size must stay a rung of the ladder).
    let margin = if stable { 1.0 } else { FIT_MARGIN };
    let fov = 2.0 * (half * margin).atan();
    (fov.is_finite() && fov > 0.0).then_some((view, fov))
}

/// Quarter octaves: the ladder a stable frustum's size and depth range climb.
const STABLE_STEPS_PER_OCTAVE: f32 = 4.0;
/// A stable frustum's aim moves in steps of its width over this (one texel of a 256² map).
const STABLE_AIM_STEPS: f32 = 256.0;
/// A stable depth range's start moves in steps of the range over this.
const STABLE_DEPTH_STEPS: f32 = 8.0;

/// The smallest rung of the quarter-octave ladder at or above `x` (> 0).
fn ladder_rung(x: f32) -> f32 {
    ((STABLE_STEPS_PER_OCTAVE * x.log2()).ceil() / STABLE_STEPS_PER_OCTAVE).exp2()
}

/// The ladder's next rung up from `x`.
fn next_rung(x: f32) -> f32 {
    x * (1.0 / STABLE_STEPS_PER_OCTAVE).exp2()
}

/// A stable fit's window in the cone's tan space holding the smoke's bounds `[x0, y0, x1, y1]`
/// ([`FIT_MARGIN`] wider): a square whose half-width is a rung of the quarter-octave ladder
/// (at most the cone's `t`) and whose middle is snapped to 1/[`STABLE_AIM_STEPS`] of its width,
/// a rung wider where the snap would leave smoke outside it.
fn stable_window([x0, y0, x1, y1]: [f32; 4], t: f32) -> (f32, f32, f32, f32) {
    let need = 0.5 * (x1 - x0).max(y1 - y0) * FIT_MARGIN;
    let mut half = ladder_rung(need.max(1e-6));
    loop {
        let step = 2.0 * half / STABLE_AIM_STEPS;
        let snap = |v: f32| (v / step).round() * step;
        let (cx, cy) = (snap(0.5 * (x0 + x1)), snap(0.5 * (y0 + y1)));
        let fits = cx - half <= x0 && cx + half >= x1 && cy - half <= y0 && cy + half >= y1;
        if fits || half >= t {
            return (cx - half, cy - half, cx + half, cy + half);
        }
        half = next_rung(half);
    }
}

/// A stable fit's radial depth range holding [`near`, `far`]: its length a rung of the
/// quarter-octave ladder, its start snapped down to 1/[`STABLE_DEPTH_STEPS`] of it, a rung
/// longer where the snap would leave the far end out.
fn stable_depth_range(near: f32, far: f32) -> (f32, f32) {
    let mut range = ladder_rung((far - near).max(1e-6));
    loop {
        let step = range / STABLE_DEPTH_STEPS;
        let start = (near / step).floor() * step;
        if start + range >= far {
            return (start.max(0.0), start + range);
        }
        range = next_rung(range);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_enclose_every_sphere() {
        let light = Spotlight {
            position: Vec3::new(0.0, 10.0, 0.0),
            target: Vec3::ZERO,
            ..Spotlight::default()
        };
        let mk = |y: f32, r: f32| Particle {
            position: Vec3::new(0.0, y, 0.0),
            velocity: Vec3::ZERO,
            age_s: 0.0,
            radius_m: r,
            density_per_m: 1.0,
            albedo: Vec3::ONE,
        };
        let ls = LightSpace::cone(&light, &[mk(5.0, 0.5), mk(2.0, 1.0)]);
        assert!((ls.near_m - 4.5).abs() < 1e-5);
        assert!((ls.far_m - 9.0).abs() < 1e-5);
        assert_eq!(ls.max_radius_m, 1.0);
        // The target is at the centre of the shadow map.
        let c = ls.clip_from_world.project_point3(Vec3::new(0.0, 1.0, 0.0));
        assert!(c.x.abs() < 1e-5 && c.y.abs() < 1e-5);
        // The view and tan(fov/2) give the same NDC as the full projection.
        let p = Vec3::new(1.5, 2.0, -0.7);
        let (v, c) = (
            ls.view_from_world.transform_point3(p),
            ls.clip_from_world.project_point3(p),
        );
        let ndc = v.truncate() / (-v.z * ls.tan_half_fov);
        assert!((ndc.x - c.x).abs() < 1e-5 && (ndc.y - c.y).abs() < 1e-5);
        assert!((ls.mean_radius_m - 0.75).abs() < 1e-6);
        assert!((ls.mean_dist_m - 6.5).abs() < 1e-5);
    }

    fn puff(position: Vec3, radius_m: f32) -> Particle {
        Particle {
            position,
            velocity: Vec3::ZERO,
            age_s: 0.0,
            radius_m,
            density_per_m: 1.0,
            albedo: Vec3::ONE,
        }
    }

    #[test]
    fn a_stable_frustum_holds_the_smoke_and_keeps_still_while_the_smoke_moves_a_little() {
        let light = Spotlight {
            position: Vec3::new(-6.0, 8.0, 4.0),
            target: Vec3::new(0.4, 2.0, 0.0),
            cone_angle_deg: 34.0,
            ..Spotlight::default()
        };
        let smoke = |shift: f32| -> Vec<Particle> {
            (0..40)
                .map(|i| {
                    let f = i as f32;
                    puff(
                        Vec3::new(1.0 + 0.05 * f + shift, 1.5 + 0.07 * f, -0.5 + 0.03 * f),
                        0.2 + 0.01 * f,
                    )
                })
                .collect()
        };
        let (a, b) = (smoke(0.0), smoke(1e-4));
        let stable = |p: &[Particle]| LightSpace::faces(&light, p, Framing::Stable)[0];
        let fit = |p: &[Particle]| LightSpace::faces(&light, p, Framing::Fit)[0];
        // A tenth of a millimetre of drift moves the fitted frustum, not the stable one.
        assert_ne!(fit(&a).clip_from_world, fit(&b).clip_from_world);
        assert_eq!(stable(&a).clip_from_world, stable(&b).clip_from_world);
        assert_eq!(
            (stable(&a).near_m, stable(&a).far_m),
            (stable(&b).near_m, stable(&b).far_m)
        );
        // It holds every sphere's centre and surface along the light's rays (within the map,
        // within its radial range), and costs at most a quarter octave and a snap of width.
        let s = stable(&a);
        let f = fit(&a);
        for p in &a {
            let ndc = s.clip_from_world.project_point3(p.position);
            assert!(ndc.x.abs() < 1.0 && ndc.y.abs() < 1.0, "{ndc}");
            let d = p.position.distance(light.position);
            assert!(s.near_m <= d - p.radius_m && s.far_m >= d + p.radius_m);
        }
        assert!(s.tan_half_fov >= f.tan_half_fov / FIT_MARGIN);
        assert!(
            s.tan_half_fov <= f.tan_half_fov * 2f32.powf(0.25) * 1.02,
            "{} vs {}",
            s.tan_half_fov,
            f.tan_half_fov
        );
        let (fr, sr) = (f.far_m - f.near_m, s.far_m - s.near_m);
        assert!(sr >= fr && sr <= 2.0 * fr, "{sr} vs {fr}");
        // Half a metre of drift: the stable frustum steps to follow (and still holds it all).
        let moved = smoke(0.5);
        let sm = stable(&moved);
        assert_ne!(sm.clip_from_world, s.clip_from_world);
        for p in &moved {
            let ndc = sm.clip_from_world.project_point3(p.position);
            assert!(ndc.x.abs() < 1.0 && ndc.y.abs() < 1.0, "{ndc}");
        }
    }

    #[test]
    fn the_stable_ladders_round_up_to_quarter_octaves_and_snap_within_them() {
        assert_eq!(ladder_rung(1.0), 1.0);
        assert!((ladder_rung(1.01) - 2f32.powf(0.25)).abs() < 1e-6);
        assert!((ladder_rung(0.3) - 2f32.powf(-1.5)).abs() < 1e-6);
        let (near, far) = stable_depth_range(5.03, 7.91);
        let range = far - near;
        // 2.88 m rounds up to 2^1.75 = 3.36 m, its start down to an eighth of it.
        assert!((range - 2f32.powf(1.75)).abs() < 1e-5, "{range}");
        assert!(near <= 5.03 && far >= 7.91);
        assert!(((near / (range / 8.0)).round() * range / 8.0 - near).abs() < 1e-5);
        let (x0, y0, x1, y1) = stable_window([0.1, -0.2, 0.3, 0.05], 1.0);
        assert!(x0 <= 0.1 && y0 <= -0.2 && x1 >= 0.3 && y1 >= 0.05);
        assert!(((x1 - x0) - (y1 - y0)).abs() < 1e-6, "square");
    }

    #[test]
    fn a_fitted_frustum_holds_every_sphere_and_is_narrower_than_the_cone() {
        let light = Spotlight {
            position: Vec3::new(-6.0, 8.0, 4.0),
            target: Vec3::new(0.4, 2.0, 0.0),
            cone_angle_deg: 34.0,
            ..Spotlight::default()
        };
        // Smoke off the cone's axis, on one side of it.
        let particles: Vec<Particle> = (0..40)
            .map(|i| {
                let f = i as f32;
                puff(
                    Vec3::new(1.0 + 0.05 * f, 1.5 + 0.07 * f, -0.5 + 0.03 * f),
                    0.2 + 0.01 * f,
                )
            })
            .collect();
        let cone = LightSpace::faces(&light, &particles, Framing::Cone)[0];
        let fit = LightSpace::faces(&light, &particles, Framing::Fit)[0];
        assert!(
            fit.tan_half_fov < 0.5 * cone.tan_half_fov,
            "{} vs {}",
            fit.tan_half_fov,
            cone.tan_half_fov
        );
        // Both keep the cone for the occluders, and the same radial bounds.
        assert_eq!(fit.cone_view_from_world, cone.view_from_world);
        assert_eq!(fit.cone_tan_half_fov, cone.tan_half_fov);
        assert_eq!((fit.near_m, fit.far_m), (cone.near_m, cone.far_m));
        // Every point of every sphere lands inside the fitted map, and some come within the
        // margin of its edge (the fit is tight).
        let mut widest = 0.0f32;
        for p in &particles {
            for i in 0..200 {
                // Points spread over the sphere (a golden-angle spiral).
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 200.0;
                let a = i as f32 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                let q = p.position + Vec3::new(r * a.cos(), r * a.sin(), z) * p.radius_m;
                let ndc = fit.clip_from_world.project_point3(q);
                widest = widest.max(ndc.x.abs()).max(ndc.y.abs());
            }
        }
        assert!(widest <= 1.0 / FIT_MARGIN + 1e-4, "{widest}");
        assert!(widest > 0.97 / FIT_MARGIN, "{widest}");
    }

    #[test]
    fn smoke_around_the_light_or_outside_the_cone_keeps_the_cone() {
        let light = Spotlight {
            position: Vec3::new(0.0, 10.0, 0.0),
            target: Vec3::ZERO,
            ..Spotlight::default()
        };
        let cone = LightSpace::cone(&light, &[]);
        for particles in [
            vec![puff(Vec3::new(0.0, 10.2, 0.0), 0.5)],
            vec![puff(Vec3::new(0.0, 20.0, 0.0), 0.5)],
            vec![],
        ] {
            let fit = LightSpace::faces(&light, &particles, Framing::Fit)[0];
            assert_eq!(fit.view_from_world, cone.view_from_world);
            assert_eq!(fit.tan_half_fov, cone.tan_half_fov);
        }
    }

    #[test]
    fn the_texels_covering_a_sphere_are_its_disc() {
        let light = Spotlight {
            position: Vec3::new(0.0, 10.0, 0.0),
            target: Vec3::ZERO,
            cone_angle_deg: 30.0,
            ..Spotlight::default()
        };
        let (d, r, res) = (8.0f32, 0.5f32, 512u32);
        let particles = [puff(Vec3::new(0.0, 10.0 - d, 0.0), r)];
        for framing in [Framing::Cone, Framing::Fit] {
            let space = LightSpace::faces(&light, &particles, framing)[0];
            // The disc's radius in texels: tan of the angle the sphere subtends over the map's
            // half-width in tan units, times half the map's side.
            let radius_px = (r / d).asin().tan() / space.tan_half_fov * res as f32 * 0.5;
            let disc = std::f32::consts::PI * radius_px * radius_px;
            let counted = space.texels_covering_smoke(&particles, None, res) as f32;
            assert!(
                (counted / disc - 1.0).abs() < 0.02,
                "{framing:?}: {counted} vs {disc}"
            );
            // A box around the sphere covers at least as much.
            let boxed = space.texels_covering_smoke(
                &[],
                Some((particles[0].position - r, particles[0].position + r)),
                res,
            );
            assert!(boxed as f32 >= counted, "{boxed} vs {counted}");
        }
    }
}
