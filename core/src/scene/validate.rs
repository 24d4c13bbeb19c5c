//! Range checks for scene fields. Every message names the field, the value and the allowed range.

use glam::Vec3;

use super::{ParamValue, Scene};

/// Hard limits shared by the scene checks and the CLI.
pub struct Limits {
    pub max_particles: u32,
    pub max_size_px: u32,
}

pub const LIMITS: Limits = Limits {
    max_particles: 4_000_000,
    max_size_px: 8192,
};

struct Checker {
    errors: Vec<String>,
}

impl Checker {
    fn range(&mut self, field: &str, value: f32, min: f32, max: f32, inclusive: bool) {
        let ok = value.is_finite()
            && if inclusive {
                (min..=max).contains(&value)
            } else {
                value > min && value < max
            };
        if !ok {
            let (open, close) = if inclusive { ('[', ']') } else { ('(', ')') };
            self.errors.push(format!(
                "{field} = {value} is out of range: allowed {open}{min}, {max}{close}"
            ));
        }
    }

    fn at_least(&mut self, field: &str, value: f32, min: f32) {
        if !(value.is_finite() && value >= min) {
            self.errors.push(format!(
                "{field} = {value} is out of range: must be >= {min}"
            ));
        }
    }

    fn positive(&mut self, field: &str, value: f32) {
        if !(value.is_finite() && value > 0.0) {
            self.errors
                .push(format!("{field} = {value} is out of range: must be > 0"));
        }
    }

    fn int_range(&mut self, field: &str, value: u64, min: u64, max: u64) {
        if !(min..=max).contains(&value) {
            self.errors.push(format!(
                "{field} = {value} is out of range: allowed {min}..={max}"
            ));
        }
    }

    fn finite(&mut self, field: &str, value: Vec3) {
        if !value.is_finite() {
            self.errors
                .push(format!("{field} = {value} must be finite"));
        }
    }

    fn each_in(&mut self, field: &str, value: Vec3, min: f32, max: f32) {
        if !(value.is_finite()
            && value.cmpge(Vec3::splat(min)).all()
            && value.cmple(Vec3::splat(max)).all())
        {
            self.errors.push(format!(
                "{field} = {value} is out of range: each component in [{min}, {max}]"
            ));
        }
    }

    fn each_at_least(&mut self, field: &str, value: Vec3, min: f32) {
        if !(value.is_finite() && value.cmpge(Vec3::splat(min)).all()) {
            self.errors.push(format!(
                "{field} = {value} is out of range: each component must be >= {min}"
            ));
        }
    }

    fn distinct(&mut self, field_a: &str, a: Vec3, field_b: &str, b: Vec3) {
        if a.is_finite() && b.is_finite() && a.distance(b) < 1e-4 {
            self.errors.push(format!(
                "{field_a} and {field_b} must differ (both are {a})"
            ));
        }
    }
}

pub(super) fn validate(scene: &Scene) -> Result<(), String> {
    let mut c = Checker { errors: Vec::new() };
    let max_px = u64::from(LIMITS.max_size_px);

    c.int_range("output.width_px", scene.output.width_px.into(), 1, max_px);
    c.int_range("output.height_px", scene.output.height_px.into(), 1, max_px);

    let cam = &scene.camera;
    c.finite("camera.position", cam.position);
    c.finite("camera.target", cam.target);
    c.distinct("camera.position", cam.position, "camera.target", cam.target);
    c.range("camera.fov_y_deg", cam.fov_y_deg, 1.0, 170.0, false);
    c.positive("camera.near_m", cam.near_m);
    if cam.far_m.is_finite() && cam.near_m.is_finite() && cam.far_m <= cam.near_m {
        c.errors.push(format!(
            "camera.far_m = {} is out of range: must be > camera.near_m ({})",
            cam.far_m, cam.near_m
        ));
    }

    let light = &scene.light;
    c.finite("light.position", light.position);
    c.finite("light.target", light.target);
    if light.kind.is_spot() {
        c.distinct(
            "light.position",
            light.position,
            "light.target",
            light.target,
        );
    }
    c.range(
        "light.cone_angle_deg",
        light.cone_angle_deg,
        0.0,
        80.0,
        false,
    );
    c.range("light.penumbra", light.penumbra, 0.0, 1.0, true);
    c.each_at_least("light.color", light.color, 0.0);
    c.at_least("light.intensity", light.intensity, 0.0);

    c.range("ground.height_m", scene.ground.height_m, -1e4, 1e4, true);
    c.positive("ground.size_m", scene.ground.size_m);
    c.each_in("ground.albedo", scene.ground.albedo, 0.0, 1.0);

    if scene.boxes.len() > super::MAX_BOXES {
        c.errors.push(format!(
            "boxes: {} boxes, more than the {} a scene may hold (the reference tests every box \
             at every point it lights)",
            scene.boxes.len(),
            super::MAX_BOXES
        ));
    }
    for (i, b) in scene.boxes.iter().enumerate() {
        c.finite(&format!("boxes[{i}].center"), b.center);
        if !(b.size.is_finite() && b.size.cmpgt(Vec3::ZERO).all()) {
            c.errors.push(format!(
                "boxes[{i}].size = {} is out of range: each component must be > 0",
                b.size
            ));
        }
        c.each_in(&format!("boxes[{i}].albedo"), b.albedo, 0.0, 1.0);
    }

    // One `[emitter]` is named `emitter`, an array's entries `emitters[i]`.
    let single = scene.emitters.len() == 1;
    for (i, e) in scene.emitters.iter().enumerate() {
        let at = if single {
            "emitter".to_owned()
        } else {
            format!("emitters[{i}]")
        };
        c.int_range(
            &format!("{at}.count"),
            e.count.into(),
            1,
            LIMITS.max_particles.into(),
        );
        c.finite(&format!("{at}.position"), e.position);
        c.at_least(&format!("{at}.source_radius_m"), e.source_radius_m, 0.0);
        c.finite(&format!("{at}.velocity_m_per_s"), e.velocity_m_per_s);
        c.at_least(
            &format!("{at}.velocity_spread_m_per_s"),
            e.velocity_spread_m_per_s,
            0.0,
        );
        c.at_least(&format!("{at}.buoyancy_m_per_s2"), e.buoyancy_m_per_s2, 0.0);
        c.positive(&format!("{at}.buoyancy_decay_s"), e.buoyancy_decay_s);
        c.at_least(
            &format!("{at}.turbulence_m_per_s2"),
            e.turbulence_m_per_s2,
            0.0,
        );
        c.positive(&format!("{at}.turbulence_scale_m"), e.turbulence_scale_m);
        c.at_least(&format!("{at}.drag_per_s"), e.drag_per_s, 0.0);
        c.positive(&format!("{at}.lifetime_s"), e.lifetime_s);
        c.positive(&format!("{at}.radius_birth_m"), e.radius_birth_m);
        c.at_least(&format!("{at}.growth_m_per_s"), e.growth_m_per_s, 0.0);
        c.at_least(&format!("{at}.density_per_m"), e.density_per_m, 0.0);
        c.range(&format!("{at}.fade_in"), e.fade_in, 0.0, 0.5, true);
        c.range(&format!("{at}.fade_out"), e.fade_out, 0.0, 0.5, true);
        c.each_in(&format!("{at}.albedo"), e.albedo, 0.0, 1.0);
        c.range(
            &format!("{at}.albedo_jitter"),
            e.albedo_jitter,
            0.0,
            0.999,
            true,
        );
    }
    match &scene.particles {
        None if scene.emitters.is_empty() && scene.volume.is_none() => {
            c.errors
                .push("emitters: the scene has no emitter: give at least one".to_owned());
        }
        None => {}
        Some(p) => {
            if p.file.trim().is_empty() {
                c.errors
                    .push("particles.file is empty: give the particle file's path".to_owned());
            }
            c.positive("particles.frame_rate_hz", p.frame_rate_hz);
            c.positive("particles.radius_m", p.radius_m);
            c.at_least("particles.density_per_m", p.density_per_m, 0.0);
            c.each_in("particles.albedo", p.albedo, 0.0, 1.0);
        }
    }
    let total = scene.particle_count();
    if !single && total > u64::from(LIMITS.max_particles) {
        c.errors.push(format!(
            "emitters: {total} particles in all is too many: at most {}",
            LIMITS.max_particles
        ));
    }

    let w = &scene.wind;
    c.finite("wind.direction", w.direction);
    c.at_least("wind.strength_m_per_s", w.strength_m_per_s, 0.0);
    if w.strength_m_per_s > 0.0 && w.direction.length() < 1e-6 {
        c.errors.push(format!(
            "wind.direction = {} must be non-zero when wind.strength_m_per_s > 0",
            w.direction
        ));
    }
    c.at_least("wind.start_s", w.start_s, 0.0);
    c.at_least("wind.ramp_s", w.ramp_s, 0.0);

    c.range("sim.duration_s", scene.sim.duration_s, 0.0, 600.0, true);
    c.range("sim.step_s", scene.sim.step_s, 0.0, 1.0, false);
    if scene.sim.step_s > 0.0 && scene.sim.duration_s / scene.sim.step_s > 1e6 {
        c.errors.push(format!(
            "sim.duration_s / sim.step_s = {} steps is too many: at most 1000000",
            scene.sim.duration_s / scene.sim.step_s
        ));
    }

    c.int_range(
        "shadow.resolution_px",
        scene.shadow.resolution_px.into(),
        1,
        max_px,
    );
    c.int_range(
        "shadow.occluder_resolution_px",
        scene.shadow.occluder_resolution_px.into(),
        16,
        max_px,
    );
    c.range(
        "shadow.history",
        scene.shadow.history,
        0.0,
        super::MAX_HISTORY,
        true,
    );
    for (key, value) in &scene.shadow.params {
        // Which keys exist, their ranges and their choices are the techniques' registry's to
        // say; it checks them when a technique is created from these settings
        // (`shadow::check_params`).
        if let ParamValue::Number(value) = value
            && !value.is_finite()
        {
            c.errors.push(format!(
                "shadow.params.{key} = {value} is not a finite number"
            ));
        }
    }

    let s = &scene.shading;
    c.range("shading.hg_g", s.hg_g, -1.0, 1.0, false);
    c.each_at_least("shading.ambient", s.ambient, 0.0);
    c.each_at_least("shading.background", s.background, 0.0);
    c.positive("shading.exposure", s.exposure);
    if let Some(volume) = &scene.volume {
        c.errors.extend(volume.problems());
    }

    if c.errors.is_empty() {
        Ok(())
    } else {
        Err(c.errors.join("; "))
    }
}
