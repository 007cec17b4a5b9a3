//! Polygon parts on a planar plate run four at a time in lanes (the friction of four parts'
//! sliding solves taken together): the same to the bit as an independent loop of the one-part
//! step (`Stepper::step_request`, its solve in a lane of its own), and a part's trajectory the same to
//! the bit whatever parts share its lanes and however many threads run them.

mod common;

use common::{extrapolate, pentagon, uniform, HISTORY, TRUSTED};
use upm_core::motion::PlateMotion;
use upm_core::polygon::{Polygon, Request, Stepper};
use upm_core::sim::{simulate, Config, Parts, Trajectory};
use upm_core::waveform::{Harmonics, Waveform};

const G: f64 = 9.81;

fn regular(n: usize, radius: f64, stretch: f64) -> Polygon {
    let v: Vec<[f64; 2]> = (0..n)
        .map(|k| {
            let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            [stretch * radius * a.cos(), radius * a.sin()]
        })
        .collect();
    Polygon::new("p", &v).unwrap()
}

/// Shapes of 3 to 20 edges (more than a block of the AVX2 build's 16), one on three feet.
fn shapes() -> Vec<Polygon> {
    let mut tripod = regular(4, 0.012, 1.5);
    tripod
        .set_feet(
            "feet",
            Some([[0.01, 0.0], [-0.008, 0.006], [-0.006, -0.007]]),
        )
        .unwrap();
    vec![
        regular(6, 0.008, 1.0),
        regular(3, 0.01, 1.0),
        pentagon(),
        regular(4, 0.009, 2.0),
        regular(20, 0.01, 1.3),
        tripod,
        regular(6, 0.008, 1.0),
    ]
}

/// A plate rotating back and forth about a point off the parts, 35 Hz, and a translation on top.
fn motion() -> PlateMotion {
    let f = 35.0;
    let rot = PlateMotion::rotation(
        [0.03, -0.02],
        Waveform::Harmonics(Harmonics::new(vec![0.0], vec![0.5, -0.25], f).unwrap()),
    )
    .unwrap();
    let trans = PlateMotion::translation(
        [0.6, 0.8],
        Waveform::Harmonics(Harmonics::two_harmonic(0.5, 1.57, 0.05, f).unwrap()),
    )
    .unwrap();
    PlateMotion::sequence(vec![
        rot.clone().for_duration(3.0 / f).unwrap(),
        trans.for_duration(1.0 / f).unwrap(),
        rot.for_duration(2.0 / f).unwrap(),
    ])
    .unwrap()
}

fn parts(shapes: &[Polygon]) -> Parts {
    let n = shapes.len();
    let u = uniform(4 * n, 7);
    Parts {
        position: (0..n).map(|i| [0.05 * u[i], 0.05 * u[n + i]]).collect(),
        velocity: vec![[0.0; 2]; n],
        mu: (0..n).map(|i| 0.3 + 0.1 * u[2 * n + i].abs()).collect(),
        mu_s: (0..n).map(|i| 0.4 + 0.1 * u[2 * n + i].abs()).collect(),
        radius: vec![0.0; n],
        angle: (0..n).map(|i| 3.0 * u[3 * n + i]).collect(),
        spin: (0..n).map(|i| 4.0 * u[3 * n + i] + 1.0).collect(),
        polygons: shapes.iter().cloned().enumerate().collect(),
    }
}

fn cfg(steps: usize) -> Config {
    Config {
        dt: 1.0 / 35.0 / 400.0,
        duration: steps as f64 / 35.0 / 400.0,
        g: G,
        plate_size: None,
        record_every: 1,
        tilt: [0.0; 2],
    }
}

fn turn([c, s]: [f64; 2], p: [f64; 2]) -> [f64; 2] {
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

/// The integrator's polygon step written out (docs/polygons.md): the implicit step of the
/// relative twist in the part's frame (`Stepper::step_request`, one part at a time), the twists
/// of up to its last seven steps that slid on one after another extrapolated by a polynomial
/// for the next solve's start (weights `(-1)^j C(n, j + 1)`, the latest first), with the
/// contraction the last solve measured (up to 32 solves in a row), then the trapezoid. Returns
/// the origin, the velocity, the angle and the stuck flag after every step.
fn reference(
    motion: &PlateMotion,
    p: &Parts,
    i: usize,
    cfg: &Config,
) -> Vec<([f64; 2], [f64; 2], f64, bool)> {
    let shape = &p.polygons[i].1;
    let stepper = Stepper::new(shape.clone());
    let steps = (cfg.duration / cfg.dt).round() as usize;
    let mut table = Vec::new();
    motion.velocities_into(0..steps, cfg.dt, &mut table);
    let (mut angle, mut spin, mut v) = (p.angle[i], p.spin[i], p.velocity[i]);
    let off = turn([angle.cos(), angle.sin()], shape.centroid);
    let mut c = [p.position[i][0] + off[0], p.position[i][1] + off[1]];
    let u0 = motion.velocity(0.0);
    let surface0 = [u0[0] - u0[2] * c[1], u0[1] + u0[2] * c[0]];
    let mut stuck = v == surface0 && spin == u0[2];
    let (mut history, mut slid) = ([[0.0; 3]; HISTORY], 0);
    let (mut contraction, mut trusted) = (None, 0);
    // the angle's cosine and sine: a turn below 1e-3 rad rotates them by its series, every
    // 16th turn (or a larger one) takes the library's
    let (mut cs, mut turns) = ([angle.cos(), angle.sin()], 0);
    let mut out = Vec::new();
    for u in table {
        let surface = [u[0] - u[2] * c[1], u[1] + u[2] * c[0]];
        let free = [v[0] - surface[0], v[1] - surface[1]];
        let local = turn([cs[0], -cs[1]], free);
        let guess = extrapolate(&history, slid);
        let st = stepper
            .step_request(&Request {
                free: [local[0], local[1], spin - u[2]],
                slide: p.mu[i] * G * cfg.dt,
                hold: p.mu_s[i] * G * cfg.dt,
                was_stuck: stuck,
                guess: (!stuck).then_some(guess),
                contraction: contraction.filter(|_| trusted < TRUSTED),
            })
            .unwrap();
        let w = turn(cs, [st.w[0], st.w[1]]);
        let (nv, nspin) = ([surface[0] + w[0], surface[1] + w[1]], u[2] + st.w[2]);
        c = [
            c[0] + 0.5 * (v[0] + nv[0]) * cfg.dt,
            c[1] + 0.5 * (v[1] + nv[1]) * cfg.dt,
        ];
        let turned = angle + 0.5 * (spin + nspin) * cfg.dt;
        if turned != angle {
            let d = turned - angle;
            turns += 1;
            if turns >= 16 || d.abs() >= 1e-3 {
                (cs, turns) = ([turned.cos(), turned.sin()], 0);
            } else {
                let d2 = d * d;
                let c = 1.0 - 0.5 * d2 * (1.0 - d2 / 12.0);
                let s = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0));
                cs = [cs[0] * c - cs[1] * s, cs[1] * c + cs[0] * s];
            }
        }
        angle = turned;
        (v, spin, stuck) = (nv, nspin, st.stuck);
        if st.w == [0.0; 3] {
            slid = 0;
        } else {
            history.rotate_right(1);
            history[0] = st.w;
            slid = (slid + 1).min(HISTORY);
        }
        (contraction, trusted) = match (st.iterations, st.contraction) {
            (0, _) => (None, 0),
            (_, Some(k)) => (Some(k), 0),
            (_, None) => (contraction, trusted + 1),
        };
        let off = turn(cs, shape.centroid);
        out.push(([c[0] - off[0], c[1] - off[1]], v, angle, stuck));
    }
    out
}

#[test]
fn parts_in_lanes_follow_the_one_part_step() {
    let shapes = shapes();
    let p = parts(&shapes);
    let (motion, c) = (motion(), cfg(2400));
    let run = simulate(&motion, &p, &c).unwrap();
    let (mut slid, mut stuck) = (0, 0);
    for i in 0..shapes.len() {
        let want = reference(&motion, &p, i, &c);
        assert_eq!(want.len() + 1, run.t.len());
        for (r, (pos, v, angle, st)) in want.into_iter().enumerate() {
            let at = (r + 1) * shapes.len() + i;
            let got = run.positions[at];
            // (one part's step takes its solve in a lane of its own: the same bits)
            assert_eq!(got, pos, "part {i}, step {r}");
            assert_eq!(run.velocities[at], v, "part {i}, step {r}");
            assert_eq!(run.angles[at], angle, "part {i}, step {r}");
            assert_eq!(run.stuck[at], st, "part {i}, step {r}");
            slid += usize::from(!st);
            stuck += usize::from(st);
        }
    }
    // both regimes, in quantity
    assert!(slid > 5000 && stuck > 2000, "{slid} sliding, {stuck} stuck");
}

/// Part `i`'s recorded rows of `run` (of `m` parts), as bits.
fn bits(run: &Trajectory, m: usize, i: usize) -> Vec<u64> {
    (0..run.t.len())
        .flat_map(|r| {
            let at = r * m + i;
            let (p, v) = (run.positions[at], run.velocities[at]);
            [p[0], p[1], v[0], v[1], run.angles[at], run.spins[at]].map(f64::to_bits)
        })
        .collect()
}

#[test]
fn a_part_s_trajectory_does_not_depend_on_its_lane_fellows_or_the_threads() {
    let shapes = shapes();
    let p = parts(&shapes);
    let (motion, c) = (motion(), cfg(600));
    let all = simulate(&motion, &p, &c).unwrap();
    let m = shapes.len();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let serial = one.install(|| simulate(&motion, &p, &c)).unwrap();
    for (i, shape) in shapes.iter().enumerate() {
        assert_eq!(
            bits(&serial, m, i),
            bits(&all, m, i),
            "part {i}, one thread"
        );
        // alone, in the first lane of its own
        let single = Parts {
            position: vec![p.position[i]],
            velocity: vec![p.velocity[i]],
            mu: vec![p.mu[i]],
            mu_s: vec![p.mu_s[i]],
            radius: vec![0.0],
            angle: vec![p.angle[i]],
            spin: vec![p.spin[i]],
            polygons: vec![(0, shape.clone())],
        };
        let alone = simulate(&motion, &single, &c).unwrap();
        assert_eq!(bits(&alone, 1, 0), bits(&all, m, i), "part {i} alone");
    }
}
