//! Tests of the velocity table ([`super`]).
use std::f64::consts::PI;

use super::*;
use crate::waveform::{BangBang, Harmonics};

/// A program with every kind of item: enveloped rotation, jet and translation, a bang-bang
/// drive, samples, rest, and a harmonic drive that repeats forever.
fn program() -> PlateMotion {
    let two = |f: f64| Harmonics::new(vec![0.7, -0.35], vec![0.1, 0.05], f).unwrap();
    let rot = PlateMotion::rotation([0.03, -0.02], two(35.0).into())
        .unwrap()
        .with_envelope(0.05, 0.1, 0.07)
        .unwrap();
    let jet = PlateMotion::jet([0.01, 0.02], [0.6, 0.8], 0.06, 0.3, 50.0)
        .unwrap()
        .with_envelope(0.12, 0.11, 0.12)
        .unwrap();
    let tr = PlateMotion::translation([1.0, 0.0], two(25.0).into())
        .unwrap()
        .with_envelope(0.06, 0.0, 0.06)
        .unwrap();
    let bang = PlateMotion::translation([0.0, 1.0], BangBang::new(0.3, 20.0, 0.02).unwrap().into())
        .unwrap()
        .for_duration(0.05)
        .unwrap();
    let samples =
        PlateMotion::from_samples(&[0.0, 0.01, 0.03], &[[0.0; 3], [0.1, 0.0, 1.0], [0.0; 3]])
            .unwrap();
    let rest = PlateMotion::rest(0.013).unwrap();
    let forever = PlateMotion::translation([0.0, 1.0], two(70.0).into()).unwrap();
    PlateMotion::sequence(vec![rot, jet, rest, tr, bang, samples, forever]).unwrap()
}

/// How far the table may lie from the direct evaluation at time `t`: both round the phase,
/// the direct one once from `w t` (about `w t` units in the last place, the larger as time
/// goes on), the table over at most `RESEED` turns; the program's velocities stay below 2.
fn tolerance(t: f64) -> f64 {
    let top = 2.0 * PI * 140.0; // the highest harmonic of the drive that repeats
    4.0 * f64::EPSILON * (RESEED as f64 + top * t) * 2.0
}

#[test]
fn the_table_is_the_velocity_at_each_step() {
    let m = program();
    let dt = 1.0 / (24.0 * 140.0);
    let n = (1.2 / dt) as usize;
    let mut table = Vec::new();
    fill(&m, 0..n, dt, &mut table);
    for (s, got) in table.iter().enumerate() {
        let t = sample_time(s, dt);
        let want = m.velocity(t);
        for k in 0..3 {
            let bound = tolerance(t);
            assert!(
                (got[k] - want[k]).abs() <= bound,
                "step {s}: {got:?} against {want:?}"
            );
        }
    }
    assert!(table.iter().any(|u| u[2].abs() > 1.0), "the program moves");
}

#[test]
fn the_table_does_not_depend_on_how_the_steps_are_split() {
    let m = program();
    let dt = 1.0 / (24.0 * 140.0);
    // (longer than the span `fill` samples at a time)
    let n = (1.5 / dt) as usize;
    assert!(n > SPAN);
    let mut whole = Vec::new();
    fill(&m, 0..n, dt, &mut whole);
    for block in [1, 7, 31, 32, 33, 100, 517] {
        let mut parts = Vec::new();
        let mut at = 0;
        while at < n {
            let end = (at + block).min(n);
            fill(&m, at..end, dt, &mut parts);
            at = end;
        }
        let same = whole
            .iter()
            .zip(&parts)
            .all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        assert!(same && parts.len() == n, "blocks of {block} steps");
    }
}

/// [`program`] with every centre, direction, amplitude and coefficient changed by `k`, and
/// its timing kept.
fn moved(k: f64) -> PlateMotion {
    let two = |f: f64| Harmonics::new(vec![0.7 - k, -0.35], vec![0.1, 0.05 + k], f).unwrap();
    let rot = PlateMotion::rotation([0.03 + k, -0.02], two(35.0).into())
        .unwrap()
        .with_envelope(0.05, 0.1, 0.07)
        .unwrap();
    let jet = PlateMotion::jet([0.01, 0.02 - k], [0.8, 0.6], 0.06 + k, 0.3, 50.0)
        .unwrap()
        .with_envelope(0.12, 0.11, 0.12)
        .unwrap();
    let tr = PlateMotion::translation([k, 1.0], two(25.0).into())
        .unwrap()
        .with_envelope(0.06, 0.0, 0.06)
        .unwrap();
    let bang = PlateMotion::rotation([k, 0.0], BangBang::new(0.3, 20.0, 0.02).unwrap().into())
        .unwrap()
        .for_duration(0.05)
        .unwrap();
    let samples =
        PlateMotion::from_samples(&[0.0, 0.01, 0.03], &[[0.0; 3], [0.1, k, 1.0], [0.0; 3]])
            .unwrap();
    let rest = PlateMotion::rest(0.013).unwrap();
    let forever = PlateMotion::rotation([k, k], two(70.0).into()).unwrap();
    PlateMotion::sequence(vec![rot, jet, rest, tr, bang, samples, forever]).unwrap()
}

#[test]
fn motions_sharing_their_timing_share_the_phasors_bitwise() {
    let motions = [program(), moved(0.01), moved(-0.02), moved(0.03)];
    let lead = motions[0].timing();
    assert!(motions.iter().all(|m| m.timing() == lead));
    let dt = 1.0 / (24.0 * 140.0);
    let n = (1.2 / dt) as usize;
    let refs: Vec<&PlateMotion> = motions.iter().collect();
    for range in [0..n, 517..n - 3, 1000..1001] {
        let mut all = vec![Vec::new(); motions.len()];
        fill_many(&refs, range.clone(), dt, &mut all);
        for (m, got) in motions.iter().zip(&all) {
            let mut alone = Vec::new();
            fill(m, range.clone(), dt, &mut alone);
            let same = alone.len() == got.len()
                && alone
                    .iter()
                    .zip(got)
                    .all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(same, "steps {range:?}");
        }
    }
    // and it is the velocity at each step, motion by motion
    let mut table = Vec::new();
    fill(&motions[2], 0..n, dt, &mut table);
    for (s, got) in table.iter().enumerate() {
        let (t, want) = (sample_time(s, dt), motions[2].velocity(sample_time(s, dt)));
        assert!(got
            .iter()
            .zip(want)
            .all(|(g, w)| (g - w).abs() <= tolerance(t)));
    }
}

/// A jet at `f` Hz with an envelope of attack `attack`.
fn jet(f: f64, attack: f64) -> PlateMotion {
    PlateMotion::jet([0.0; 2], [1.0, 0.0], 0.06, 0.3, f)
        .unwrap()
        .with_envelope(attack, 0.1, 0.1)
        .unwrap()
}

/// A rotation about the origin at 50 Hz (`cos` and `sin` its harmonics), enveloped as [`jet`]
/// with an attack of 0.1 s.
fn rotation(cos: Vec<f64>, sin: Vec<f64>) -> PlateMotion {
    PlateMotion::rotation([0.0; 2], Harmonics::new(cos, sin, 50.0).unwrap().into())
        .unwrap()
        .with_envelope(0.1, 0.1, 0.1)
        .unwrap()
}

#[test]
fn another_frequency_envelope_or_duration_is_another_timing() {
    let base = jet(50.0, 0.1).timing();
    assert_ne!(base, jet(40.0, 0.1).timing());
    assert_ne!(base, jet(50.0, 0.12).timing());
    assert_ne!(base, jet(50.0, 0.1).for_duration(0.2).unwrap().timing());
    let spin = rotation(vec![1.0], vec![0.0]);
    assert_ne!(base, spin.timing(), "a jet also turns its 2/3 phase");
    assert_eq!(base, jet(50.0, 0.1).timing());
}

#[test]
fn comparing_timings_word_by_word_is_comparing_their_keys() {
    let spin = PlateMotion::rotation(
        [0.0; 2],
        Harmonics::new(vec![1.0], vec![0.0], 50.0).unwrap().into(),
    )
    .unwrap();
    let motions = [
        jet(50.0, 0.1),
        jet(50.0, 0.1),
        jet(40.0, 0.1),
        jet(50.0, 0.12),
        jet(50.0, 0.1).for_duration(0.2).unwrap(),
        spin.clone(),
        spin.with_envelope(0.1, 0.1, 0.1).unwrap(),
        program(),
        moved(0.01),
        PlateMotion::sequence(vec![jet(50.0, 0.1), jet(50.0, 0.1)]).unwrap(),
        PlateMotion::rest(0.013).unwrap(),
    ];
    let mut alike = 0;
    for a in &motions {
        for b in &motions {
            let same = a.timing() == b.timing();
            assert_eq!(a.same_timing(b), same, "{a:?} and {b:?}");
            alike += usize::from(same);
        }
    }
    assert_eq!(
        alike,
        motions.len() + 4,
        "each with itself, the two jets and program/moved"
    );
}

#[test]
fn steps_before_the_program_and_empty_ranges() {
    let m = program();
    let mut out = Vec::new();
    fill(&m, 5..5, 1e-3, &mut out);
    assert!(out.is_empty());
    // a step far past every timed item: the repeating drive, still exact
    let dt = 1e-4;
    fill(&m, 1_000_000..1_000_040, dt, &mut out);
    for (k, u) in out.iter().enumerate() {
        let t = sample_time(1_000_000 + k, dt);
        let want = m.velocity(t);
        assert!(
            (u[1] - want[1]).abs() <= tolerance(t),
            "step {k}: {u:?} against {want:?}"
        );
    }
}

/// [`moved`] with its first drive a translation instead of a rotation, its second a rotation
/// instead of a translation, and each with a third harmonic: the same timing, unlike in kind.
fn swapped(k: f64) -> PlateMotion {
    let three = |f: f64| Harmonics::new(vec![0.7, -0.35, k], vec![0.1, 0.05, 0.2], f).unwrap();
    let tr = PlateMotion::translation([0.6, 0.8], three(35.0).into())
        .unwrap()
        .with_envelope(0.05, 0.1, 0.07)
        .unwrap();
    let rot = PlateMotion::rotation([k, 0.01], three(25.0).into())
        .unwrap()
        .with_envelope(0.06, 0.0, 0.06)
        .unwrap();
    let mut items = moved(k).items;
    items[0] = tr.items[0].clone();
    items[3] = rot.items[0].clone();
    PlateMotion {
        items,
        starts: moved(k).starts,
    }
}

#[test]
fn motions_side_by_side_are_bitwise_each_alone() {
    // Ten motions: more than one vector of eight. Alike: every jet and every drive evaluated
    // together; unlike: two of them with their drives of another kind and harmonic count.
    let alike: Vec<PlateMotion> = (0..10).map(|k| moved(0.003 * k as f64 - 0.01)).collect();
    let mut unlike = alike.clone();
    unlike[3] = swapped(0.02);
    unlike[9] = swapped(-0.01);
    let dt = 1.0 / (24.0 * 140.0);
    let n = (1.2 / dt) as usize;
    let (width, col) = (13, 2);
    for motions in [&alike, &unlike] {
        let refs: Vec<&PlateMotion> = motions.iter().collect();
        assert!(refs.iter().all(|m| m.timing() == refs[0].timing()));
        for range in [0..n, 517..n - 3, 1000..1001] {
            let phases = Phases::of(refs[0], range.clone(), dt);
            let mut values = vec![f64::NAN; 3 * width * range.len()];
            let mut out = Columns {
                values: &mut values,
                width,
            };
            phases.extend_across(&refs, range.clone(), &mut out, col);
            for (j, m) in refs.iter().enumerate() {
                let mut alone = Vec::new();
                fill(m, range.clone(), dt, &mut alone);
                for (r, u) in alone.iter().enumerate() {
                    for (c, want) in u.iter().enumerate() {
                        let got = values[(3 * r + c) * width + col + j];
                        assert_eq!(
                            got.to_bits(),
                            want.to_bits(),
                            "motion {j}, step {}, component {c}: {got} against {want}",
                            range.start + r
                        );
                    }
                }
            }
            // the columns of no motion untouched
            let mut outside = values
                .iter()
                .enumerate()
                .filter(|(i, _)| !(col..col + refs.len()).contains(&(i % width)));
            assert!(outside.clone().count() > 0 && outside.all(|(_, v)| v.is_nan()));
        }
    }
}

#[test]
fn jets_a_kernel_evaluates_are_what_the_table_holds() {
    // Eleven jets of one timing (attack 0.1 s, hold 0.1, decay 0.1, then rest) at 2400 steps/s:
    // a set of eight and one of three (its other lanes' coefficients zero).
    let dt = 1.0 / 2400.0;
    let motions: Vec<PlateMotion> = (0..11)
        .map(|j| {
            let a = 0.7 * j as f64;
            PlateMotion::jet(
                [0.01 * j as f64, -0.02],
                [a.cos(), a.sin()],
                0.05 + 0.01 * j as f64,
                0.3,
                50.0,
            )
            .unwrap()
            .with_envelope(0.1, 0.1, 0.1)
            .unwrap()
        })
        .collect();
    let refs: Vec<&PlateMotion> = motions.iter().collect();
    let phases = Phases::of(&motions[0], 0..800, dt);
    let width = 16;
    let mut table = vec![0.0; 3 * width * 800];
    let mut out = Columns {
        values: &mut table,
        width,
    };
    phases.extend_across(&refs, 0..800, &mut out, 0);
    // Steps 200..500 lie within the attack, hold and decay: three stints, in order, that cover
    // them; each lane's jet velocity, evaluated as the kernel does, is the table's to the bit.
    let stints = phases.jets(&refs, 200..500);
    assert_eq!(stints.len(), 3);
    let mut next = 200;
    for st in &stints {
        assert_eq!(st.steps.start, next);
        assert_eq!(st.samples.len(), st.steps.len());
        next = st.steps.end;
        let coef = st.coef.as_ref().expect("jets throughout");
        assert_eq!(coef.len(), 2);
        for (set, &[k, ax, ay, cx, cy]) in coef.iter().enumerate() {
            assert!(
                k[3..].iter().all(|&k| k == 0.0) || set == 0,
                "no jet past the motions"
            );
            for (s, p) in st.steps.clone().zip(st.samples) {
                for j in 0..8 {
                    let w = k[j] * p.spin;
                    let u = [ax[j] * p.feed + w * cy[j], ay[j] * p.feed - w * cx[j], w];
                    let col = 8 * set + j;
                    for (c, u) in u.iter().enumerate() {
                        if col < motions.len() {
                            let want = table[(3 * s + c) * width + col];
                            assert_eq!(u.to_bits(), want.to_bits(), "step {s}, motion {col}");
                        } else {
                            assert_eq!(*u, 0.0, "step {s}, lane {col} (no motion)");
                        }
                    }
                }
            }
        }
    }
    assert_eq!(next, 500);
    // Where the plate rests (from step 720), or a motion plays no jet, the kernel reads a table.
    let none = |stints: &[JetStint]| stints.iter().all(|st| st.coef.is_none());
    let rest = phases.jets(&refs, 700..760);
    assert_eq!(rest.len(), 2, "the decay's last steps, then the rest");
    assert!(rest[0].coef.is_some() && none(&rest[1..]));
    let mut mixed = refs.clone();
    let turn = rotation(vec![0.0], vec![0.1]);
    mixed[3] = &turn;
    assert!(none(&phases.jets(&mixed, 200..500)));
}
