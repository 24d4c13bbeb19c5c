//! The deterministic smoke emitter (thesis 3.1.2: particle systems).
//!
//! A fixed pool of `emitter.count` particles is born at a steady rate (particle `i` first at
//! `i * lifetime / count`) and each particle is re-born at the source when it dies, so after one
//! lifetime the plume is in a steady state with every particle alive. The state advances in fixed
//! steps of `sim.step_s` from t = 0 to `sim.duration_s` with semi-implicit Euler.
//!
//! Determinism by construction, at any thread count: each pool slot owns a named PRNG
//! ([`rand_pcg::Pcg32`] on its own stream, seeded from the scene seed and the slot index, see
//! [`slot_rng`]) that only that slot's births, re-births and random walk draw from, in step
//! order; the turbulence field is built from a generator seeded with the scene seed alone; a
//! step updates every particle from the previous step's state and read-only shared data (no
//! reduction, no order-dependent float sums); no wall clock. So the slots can be stepped in
//! parallel (rayon) in any order and on any number of threads: same scene => bit-identical
//! particles, whether the rayon pool has 1 thread or 16.
//!
//! Forces: buoyancy that decays with age, a divergence-free turbulent field (a sum of transverse
//! travelling plane waves), a small per-particle random walk, and drag towards the air velocity,
//! which is where the wind gust enters.
//!
//! A scene's emitters (`[[emitters]]`) are independent pools stepped on one clock in one wind:
//! each draws only from its own seed's streams, so its particles are bit for bit those it would
//! make alone, and the frame lists them emitter by emitter.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;

use crate::scene::{Emitter, Scene, Wind};

/// One simulated particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    pub position: Vec3,
    pub velocity: Vec3,
    /// Seconds since (re)birth.
    pub age_s: f32,
    /// Sphere radius in metres (grows with age).
    pub radius_m: f32,
    /// Extinction coefficient τ in 1/m, already multiplied by the age fade.
    pub density_per_m: f32,
    /// Single-scattering albedo, linear RGB.
    pub albedo: Vec3,
}

/// Number of plane waves in the turbulence field.
const TURBULENCE_WAVES: usize = 12;

/// A divergence-free, time-varying acceleration field: each wave's amplitude is perpendicular to
/// its wave vector, so every term (and the sum) has zero divergence, giving swirls, not sources.
struct Turbulence {
    waves: [Wave; TURBULENCE_WAVES],
}

struct Wave {
    wave_vector: Vec3,
    amplitude: Vec3,
    phase: f32,
    angular_speed: f32,
}

impl Turbulence {
    fn new(rng: &mut Pcg32, emitter: &Emitter) -> Self {
        let waves = std::array::from_fn(|i| {
            // Octaves: wavelength = scale / 2^(i/4), amplitude falls off as the -1/3 power of the
            // wave number, a rough Kolmogorov-like spectrum.
            let octave = (i / 4) as f32;
            let k = std::f32::consts::TAU / emitter.turbulence_scale_m * 2f32.powf(octave);
            let dir = random_unit(rng);
            let amp_dir = dir
                .any_orthonormal_pair()
                .0
                .lerp(dir.any_orthonormal_pair().1, rng.random::<f32>());
            let amp = emitter.turbulence_m_per_s2 * 2f32.powf(-octave / 3.0)
                / (TURBULENCE_WAVES as f32 / 4.0).sqrt();
            Wave {
                wave_vector: dir * k,
                amplitude: amp_dir.normalize_or_zero() * amp,
                phase: rng.random::<f32>() * std::f32::consts::TAU,
                angular_speed: 0.3 + rng.random::<f32>() * 0.7,
            }
        });
        Self { waves }
    }

    /// The field at time `t_s`, as every particle of a step evaluates it.
    fn at(&self, t_s: f32) -> FieldAt {
        let w = &self.waves;
        FieldAt {
            kx: w.each_ref().map(|w| w.wave_vector.x),
            ky: w.each_ref().map(|w| w.wave_vector.y),
            kz: w.each_ref().map(|w| w.wave_vector.z),
            offset: w.each_ref().map(|w| w.phase + w.angular_speed * t_s),
            ax: w.each_ref().map(|w| w.amplitude.x),
            ay: w.each_ref().map(|w| w.amplitude.y),
            az: w.each_ref().map(|w| w.amplitude.z),
        }
    }
}

/// The turbulence frozen at one step's time, one array per component, so that the waves go
/// through loops the compiler vectorises (the simulation's hot path: every particle, every
/// step).
struct FieldAt {
    kx: [f32; TURBULENCE_WAVES],
    ky: [f32; TURBULENCE_WAVES],
    kz: [f32; TURBULENCE_WAVES],
    /// phase + angular speed x t.
    offset: [f32; TURBULENCE_WAVES],
    ax: [f32; TURBULENCE_WAVES],
    ay: [f32; TURBULENCE_WAVES],
    az: [f32; TURBULENCE_WAVES],
}

impl FieldAt {
    /// Σ amplitude · sin(k · p + offset).
    fn accel(&self, p: Vec3) -> Vec3 {
        let mut s = [0.0; TURBULENCE_WAVES];
        #[allow(clippy::needless_range_loop)] // one index into seven arrays
        for i in 0..TURBULENCE_WAVES {
            s[i] = sin_f32(self.kx[i] * p.x + self.ky[i] * p.y + self.kz[i] * p.z + self.offset[i]);
        }
        let dot = |a: &[f32; TURBULENCE_WAVES]| a.iter().zip(&s).map(|(a, s)| a * s).sum::<f32>();
        Vec3::new(dot(&self.ax), dot(&self.ay), dot(&self.az))
    }
}

/// sin(x) from IEEE f32 additions, multiplications, min and sign operations only: no libm call,
/// so a loop of them vectorises (the turbulence's 12 waves: 2.2x less CPU per step than libm's
/// `sinf` on the development machine). x is reduced to [-π, π] by the nearest multiple of 2π
/// (2π split in two parts, Cody and Waite, so the reduction's own error stays below 1e-7 for the
/// |x| < 10^3 the turbulence produces), folded into [0, π/2] by sin(π − a) = sin(a), and the
/// Taylor polynomial to a¹¹ evaluated (truncation error below 6e-8 at π/2). Absolute error
/// against the exact sine of the f32 argument: below 1e-6 (tested).
fn sin_f32(x: f32) -> f32 {
    use std::f32::consts::{FRAC_1_PI, PI};
    /// 1.5 · 2^23: adding and subtracting it rounds an f32 below 2^22 to the nearest integer.
    const ROUND: f32 = 12_582_912.0;
    /// 2π = TAU_HI + TAU_LO, TAU_HI with 7 significant bits so that k · TAU_HI is exact.
    const TAU_HI: f32 = 6.281_25;
    const TAU_LO: f32 = 0.001_935_307_2;
    let k = (x * (0.5 * FRAC_1_PI) + ROUND) - ROUND;
    let r = (x - k * TAU_HI) - k * TAU_LO;
    // sin(r) = ±sin(|r|) = ±sin(min(|r|, π − |r|)); rounding can leave |r| a hair above π, where
    // π − |r| is a tiny negative angle, which the odd polynomial takes as it is.
    let a = r.abs();
    let a = a.min(PI - a);
    let a2 = a * a;
    let poly = 1.0
        + a2 * (-1.0 / 6.0
            + a2 * (1.0 / 120.0
                + a2 * (-1.0 / 5040.0 + a2 * (1.0 / 362_880.0 + a2 * (-1.0 / 39_916_800.0)))));
    a * poly * 1f32.copysign(r)
}

fn random_unit(rng: &mut Pcg32) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let len2 = v.length_squared();
        if len2 > 1e-4 && len2 <= 1.0 {
            return v / len2.sqrt();
        }
    }
}

/// Air velocity of the wind gust at time `t_s`.
pub fn wind_velocity(wind: &Wind, t_s: f32) -> Vec3 {
    if wind.strength_m_per_s <= 0.0 || t_s < wind.start_s {
        return Vec3::ZERO;
    }
    let ramp = if wind.ramp_s > 0.0 {
        let x = ((t_s - wind.start_s) / wind.ramp_s).clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    } else {
        1.0
    };
    wind.direction.normalize_or_zero() * wind.strength_m_per_s * ramp
}

/// Pool slot state: not yet born, or alive.
#[derive(Clone)]
struct Slot {
    particle: Particle,
    alive: bool,
    brightness: f32,
    /// This slot's own random stream ([`slot_rng`]).
    rng: Pcg32,
}

/// Slots stepped per rayon task: a step costs ~0.1 µs per particle, so this keeps the task
/// overhead small without starving threads at the thesis' 2,500 particles.
const SLOTS_PER_TASK: usize = 512;

/// The random stream of pool slot `slot` for emitter seed `seed`: PCG-32 on stream `slot` (its
/// own LCG increment), started from a state that mixes seed and slot through SplitMix64 so that
/// neighbouring slots (or seeds) do not start from neighbouring states.
pub fn slot_rng(seed: u64, slot: u32) -> Pcg32 {
    let slot = u64::from(slot);
    Pcg32::new(splitmix64(seed ^ splitmix64(slot)), slot)
}

/// SplitMix64's finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mix.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Runs the emitter from t = 0 to `scene.sim.duration_s` and returns the live particles in pool
/// order (index order, not sorted).
pub fn simulate(scene: &Scene) -> Vec<Particle> {
    simulate_until(scene, scene.sim.duration_s)
}

/// Like [`simulate`], but stops at `time_s`.
pub fn simulate_until(scene: &Scene, time_s: f32) -> Vec<Particle> {
    let mut sim = Simulation::new(scene);
    sim.advance_to(time_s);
    sim.particles()
}

/// The fixed step nearest `time_s` for steps of `step_s`: where [`Simulation::advance_to`] stops,
/// and how many steps [`simulate`] takes.
pub fn step_index(step_s: f32, time_s: f32) -> u64 {
    (time_s.max(0.0) / step_s).round() as u64
}

/// The emitters' state between fixed steps, for callers that move through time (the viewer's
/// play and scrub): stepping forward continues; going back replays from t = 0, so the state at
/// a time is always the one [`simulate_until`] gives.
pub struct Simulation {
    /// One pool per emitter, in the scene's order.
    pools: Vec<Pool>,
    wind: Wind,
    step_s: f32,
    /// Steps taken so far.
    steps: u64,
}

/// One emitter's pool: its slots, its turbulence and its birth schedule. Pools share nothing but
/// the wind and the clock, so each emitter's particles are exactly those it would make alone.
struct Pool {
    emitter: Emitter,
    turbulence: Turbulence,
    slots: Vec<Slot>,
    /// The first slot not yet born (particles are born in index order).
    next_birth: usize,
}

/// What a scene's simulated particles follow from (its emitters, wind and time step): two
/// scenes with equal inputs simulate the same particles, so a simulation can be kept.
pub type SimInputs = (Vec<Emitter>, Wind, f32);

impl Simulation {
    /// The inputs `scene`'s simulation follows from.
    pub fn inputs(scene: &Scene) -> SimInputs {
        (scene.emitters.clone(), scene.wind.clone(), scene.sim.step_s)
    }

    /// The state at t = 0.
    pub fn new(scene: &Scene) -> Self {
        Self::start(&scene.emitters, scene.wind.clone(), scene.sim.step_s)
    }

    fn start(emitters: &[Emitter], wind: Wind, step_s: f32) -> Self {
        Self {
            pools: emitters.iter().cloned().map(Pool::new).collect(),
            wind,
            step_s,
            steps: 0,
        }
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f32 {
        self.steps as f32 * self.step_s
    }

    /// Steps forward (or replays from the start) to the step nearest `time_s`.
    pub fn advance_to(&mut self, time_s: f32) {
        self.advance_to_reporting(time_s, &mut |_, _| {});
    }

    /// [`Simulation::advance_to`], calling `progress(done, total)` after each step with the
    /// steps taken and the steps this call takes in all (for a progress bar).
    pub fn advance_to_reporting(&mut self, time_s: f32, progress: &mut dyn FnMut(u64, u64)) {
        let target = step_index(self.step_s, time_s);
        if target < self.steps {
            let emitters: Vec<Emitter> = self.pools.iter().map(|p| p.emitter.clone()).collect();
            *self = Self::start(&emitters, self.wind.clone(), self.step_s);
        }
        let first = self.steps;
        while self.steps < target {
            let t = self.steps as f32 * self.step_s;
            let air = wind_velocity(&self.wind, t);
            for pool in &mut self.pools {
                pool.step(t, self.step_s, air);
            }
            self.steps += 1;
            progress(self.steps - first, target - first);
        }
    }

    /// The live particles, emitter by emitter in pool order, with their age-dependent radius,
    /// density and albedo.
    pub fn particles(&self) -> Vec<Particle> {
        let mut all = Vec::new();
        for pool in &self.pools {
            all.extend(pool.particles());
        }
        all
    }
}

impl Pool {
    fn new(e: Emitter) -> Self {
        let turbulence = Turbulence::new(&mut Pcg32::seed_from_u64(e.seed), &e);
        let empty = Particle {
            position: e.position,
            velocity: Vec3::ZERO,
            age_s: 0.0,
            radius_m: e.radius_birth_m,
            density_per_m: 0.0,
            albedo: e.albedo,
        };
        let slots = (0..e.count)
            .into_par_iter()
            .map(|i| Slot {
                particle: empty,
                alive: false,
                brightness: 1.0,
                rng: slot_rng(e.seed, i),
            })
            .collect();
        Self {
            slots,
            emitter: e,
            turbulence,
            next_birth: 0,
        }
    }

    /// One fixed step from `t` of `dt` in the air velocity `air`: the births due in it (in slot
    /// order, each from its own stream), then every live slot advanced in parallel. A slot's
    /// update reads only its own state and the shared, read-only emitter, turbulence and air
    /// velocity, so the schedule cannot change it.
    fn step(&mut self, t: f32, dt: f32, air: Vec3) {
        let e = &self.emitter;
        let count = e.count as usize;
        let birth_interval = e.lifetime_s / e.count as f32;
        let t_end = t + dt;
        while self.next_birth < count && (self.next_birth as f32) * birth_interval < t_end {
            spawn(&mut self.slots[self.next_birth], e);
            self.next_birth += 1;
        }
        let turbulence = self.turbulence.at(t);
        let turbulence = &turbulence;
        // Slots past `next_birth` are not born yet: no need to visit them.
        self.slots[..self.next_birth]
            .par_chunks_mut(SLOTS_PER_TASK)
            .for_each(|chunk| {
                for slot in chunk.iter_mut().filter(|s| s.alive) {
                    advance(slot, e, turbulence, air, dt);
                }
            });
    }

    fn particles(&self) -> Vec<Particle> {
        let e = &self.emitter;
        self.slots
            .par_iter()
            .filter(|s| s.alive)
            .map(|s| {
                let mut p = s.particle;
                p.radius_m = e.radius_birth_m + e.growth_m_per_s * p.age_s;
                p.density_per_m = e.density_per_m * age_fade(e, p.age_s);
                p.albedo = (e.albedo * s.brightness).clamp(Vec3::ZERO, Vec3::ONE);
                p
            })
            .collect()
    }
}

/// One slot's semi-implicit Euler step in the step's turbulence and air velocity, re-born at the
/// source when it reaches the end of its life.
fn advance(slot: &mut Slot, e: &Emitter, turbulence: &FieldAt, air: Vec3, dt: f32) {
    let p = &mut slot.particle;
    let buoyancy = Vec3::Y * e.buoyancy_m_per_s2 * (-p.age_s / e.buoyancy_decay_s).exp();
    let jitter = random_unit(&mut slot.rng) * (e.turbulence_m_per_s2 * 0.5);
    let accel =
        buoyancy + turbulence.accel(p.position) + jitter + (air - p.velocity) * e.drag_per_s;
    p.velocity += accel * dt;
    p.position += p.velocity * dt;
    p.age_s += dt;
    if p.age_s >= e.lifetime_s {
        spawn(slot, e);
    }
}

/// (Re)births `slot` at the source, drawing from the slot's own stream.
fn spawn(slot: &mut Slot, e: &Emitter) {
    let rng = &mut slot.rng;
    // Uniform point on the source disc (horizontal).
    let angle = rng.random::<f32>() * std::f32::consts::TAU;
    let r = e.source_radius_m * rng.random::<f32>().sqrt();
    let offset = Vec3::new(angle.cos() * r, 0.0, angle.sin() * r);
    let spread = Vec3::new(
        rng.random_range(-1.0..=1.0),
        rng.random_range(-1.0..=1.0),
        rng.random_range(-1.0..=1.0),
    ) * e.velocity_spread_m_per_s;
    let brightness = 1.0 + e.albedo_jitter * rng.random_range(-1.0..=1.0);
    slot.particle.position = e.position + offset;
    slot.particle.velocity = e.velocity_m_per_s + spread;
    slot.particle.age_s = 0.0;
    slot.alive = true;
    slot.brightness = brightness;
}

/// Opacity fade over a particle's life: ramps in over `fade_in` of the life and out over
/// `fade_out`, smoothly, so particles neither pop in nor vanish.
pub fn age_fade(e: &Emitter, age_s: f32) -> f32 {
    let x = (age_s / e.lifetime_s).clamp(0.0, 1.0);
    let smooth = |a: f32| a * a * (3.0 - 2.0 * a);
    let fade_in = if e.fade_in > 0.0 {
        smooth((x / e.fade_in).min(1.0))
    } else {
        1.0
    };
    let fade_out = if e.fade_out > 0.0 {
        smooth(((1.0 - x) / e.fade_out).min(1.0))
    } else {
        1.0
    };
    fade_in * fade_out
}

#[cfg(test)]
mod tests {
    #[test]
    fn stepping_forward_and_back_matches_simulating_from_the_start() {
        let scene = Scene::thesis_plume();
        let mut sim = Simulation::new(&scene);
        sim.advance_to(3.0);
        sim.advance_to(5.0);
        assert_eq!(sim.particles(), simulate_until(&scene, 5.0));
        sim.advance_to(2.0);
        assert_eq!(sim.particles(), simulate_until(&scene, 2.0));
        assert!((sim.time_s() - 2.0).abs() < 1e-3);
    }

    use super::*;

    fn small_scene(seed: u64) -> Scene {
        let mut scene = Scene::thesis_plume();
        scene.emitters[0].count = 300;
        scene.emitters[0].seed = seed;
        scene.sim.duration_s = 3.0;
        scene
    }

    fn bits(ps: &[Particle]) -> Vec<u32> {
        ps.iter()
            .flat_map(|p| {
                [
                    p.position.x,
                    p.position.y,
                    p.position.z,
                    p.velocity.x,
                    p.age_s,
                    p.radius_m,
                    p.density_per_m,
                    p.albedo.x,
                ]
            })
            .map(f32::to_bits)
            .collect()
    }

    #[test]
    fn same_seed_gives_bit_identical_particles() {
        let a = simulate(&small_scene(7));
        let b = simulate(&small_scene(7));
        assert!(!a.is_empty());
        assert_eq!(bits(&a), bits(&b));
    }

    /// Runs `f` on a fresh rayon pool of `threads` threads.
    fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a rayon pool")
            .install(f)
    }

    #[test]
    fn thread_count_does_not_change_a_bit() {
        // Enough slots for many rayon tasks (SLOTS_PER_TASK each), a wind gust and re-births.
        let mut scene = small_scene(11);
        scene.emitters[0].count = 6 * SLOTS_PER_TASK as u32 + 37;
        scene.emitters[0].lifetime_s = 1.5;
        scene.wind.strength_m_per_s = 2.0;
        scene.wind.start_s = 1.0;
        let one = on_threads(1, || simulate(&scene));
        assert_eq!(one.len(), scene.emitters[0].count as usize);
        for threads in [2, 3, 8] {
            let many = on_threads(threads, || simulate(&scene));
            assert_eq!(bits(&one), bits(&many), "{threads} threads");
            assert_eq!(one, many, "{threads} threads");
        }
    }

    #[test]
    fn sin_f32_is_within_1e_6_of_the_exact_sine() {
        let (mut worst, mut worst_x) = (0.0f64, 0.0f32);
        // Every argument the turbulence sees and more: |k·p| up to ~10^3 rad, 600 s of phase.
        for i in -2_000_000..=2_000_000 {
            let x = i as f32 * 7.3e-4;
            let e = (f64::from(sin_f32(x)) - f64::from(x).sin()).abs();
            if e > worst {
                worst = e;
                worst_x = x;
            }
        }
        for x in [0.0, -0.0, 1e-30, std::f32::consts::PI, 1e4, -1e4] {
            let e = (f64::from(sin_f32(x)) - f64::from(x).sin()).abs();
            if e > worst {
                worst = e;
                worst_x = x;
            }
        }
        assert!(worst < 1e-6, "worst error {worst} at {worst_x}");
        assert_eq!(sin_f32(0.0), 0.0);
    }

    #[test]
    fn slots_draw_from_distinct_streams() {
        let draws = |seed, slot| -> Vec<u32> {
            let mut rng = slot_rng(seed, slot);
            (0..8).map(|_| rng.random::<u32>()).collect()
        };
        let first = draws(2013, 0);
        assert_ne!(first, draws(2013, 1));
        assert_ne!(first, draws(2014, 0));
        assert_eq!(first, draws(2013, 0));
    }

    #[test]
    fn another_seed_gives_different_particles() {
        let a = simulate(&small_scene(7));
        let b = simulate(&small_scene(8));
        assert_eq!(
            a.len(),
            b.len(),
            "the birth schedule does not depend on the seed"
        );
        let moved = a
            .iter()
            .zip(&b)
            .filter(|(p, q)| p.position.distance(q.position) > 1e-3)
            .count();
        assert!(
            moved > a.len() * 9 / 10,
            "only {moved} of {} particles differ",
            a.len()
        );
    }

    #[test]
    fn pool_is_full_after_one_lifetime_and_partial_before() {
        let mut scene = small_scene(1);
        scene.sim.duration_s = scene.emitters[0].lifetime_s * 0.5;
        let half = simulate(&scene).len();
        scene.sim.duration_s = scene.emitters[0].lifetime_s * 2.0;
        let full = simulate(&scene).len();
        assert_eq!(full, scene.emitters[0].count as usize);
        let expected = scene.emitters[0].count as usize / 2;
        assert!(
            half.abs_diff(expected) <= 2,
            "half-life pool has {half}, expected ~{expected}"
        );
    }

    #[test]
    fn particles_rise_grow_and_fade() {
        let scene = small_scene(3);
        let ps = simulate(&scene);
        let e = &scene.emitters[0];
        for p in &ps {
            assert!(p.age_s < e.lifetime_s);
            let r = e.radius_birth_m + e.growth_m_per_s * p.age_s;
            assert!((p.radius_m - r).abs() < 1e-5);
            assert!(p.density_per_m <= e.density_per_m + 1e-6);
        }
        // Buoyancy: older particles are higher on average than young ones.
        let mean_y = |pred: &dyn Fn(&Particle) -> bool| {
            let sel: Vec<_> = ps.iter().filter(|p| pred(p)).collect();
            sel.iter().map(|p| p.position.y).sum::<f32>() / sel.len() as f32
        };
        assert!(mean_y(&|p| p.age_s > 2.0) > mean_y(&|p| p.age_s < 0.5) + 0.5);
    }

    #[test]
    fn wind_pushes_the_plume_downwind() {
        let mut calm = small_scene(5);
        calm.sim.duration_s = 6.0;
        let mut windy = calm.clone();
        windy.wind.strength_m_per_s = 3.0;
        windy.wind.direction = Vec3::X;
        windy.wind.start_s = 3.0;
        let mean_x =
            |ps: &[Particle]| ps.iter().map(|p| p.position.x).sum::<f32>() / ps.len() as f32;
        assert!(mean_x(&simulate(&windy)) > mean_x(&simulate(&calm)) + 0.5);
    }

    #[test]
    fn wind_is_zero_before_the_gust_and_full_after_the_ramp() {
        let wind = Wind {
            direction: Vec3::new(2.0, 0.0, 0.0),
            strength_m_per_s: 3.0,
            start_s: 1.0,
            ramp_s: 0.5,
        };
        assert_eq!(wind_velocity(&wind, 0.99), Vec3::ZERO);
        assert!((wind_velocity(&wind, 1.25).x - 1.5).abs() < 1e-5);
        assert_eq!(wind_velocity(&wind, 2.0), Vec3::new(3.0, 0.0, 0.0));
    }
}
