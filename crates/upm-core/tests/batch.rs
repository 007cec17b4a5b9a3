//! Batches of small worlds (run side by side, several worlds to a register tile) against the
//! same worlds simulated one at a time: bitwise the same.

use upm_core::motion::PlateMotion;
use upm_core::sim::{
    little_work, simulate, simulate_batch, simulate_stacked, Config, Parts, WorldRows,
};
use upm_core::{Error, Harmonics, Waveform};

/// Deterministic numbers in [-1, 1).
fn noise(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}

/// Settings of a run: steps of `dt` through `duration`, on a plate of side `plate_size`,
/// recording every `record_every`-th step.
fn config(dt: f64, duration: f64, plate_size: Option<f64>, record_every: usize) -> Config {
    Config {
        dt,
        duration,
        g: 9.81,
        plate_size,
        record_every,
        tilt: [0.0; 2],
    }
}

/// `b` different motions: rotations about scattered centres and translations, at 35 Hz.
fn motions(b: usize) -> Vec<PlateMotion> {
    let r = noise(b as u64, 4 * b);
    (0..b)
        .map(|w| {
            let wave: Waveform = Harmonics::new(
                vec![0.3 * r[4 * w]],
                vec![0.5, -0.25 + 0.1 * r[4 * w + 1]],
                35.0,
            )
            .unwrap()
            .into();
            if w % 3 == 2 {
                PlateMotion::translation([0.6, 0.8], wave).unwrap()
            } else {
                PlateMotion::rotation([0.05 * r[4 * w + 2], 0.05 * r[4 * w + 3]], wave).unwrap()
            }
        })
        .collect()
}

fn parts(m: usize) -> Parts {
    let r = noise(100 + m as u64, 4 * m);
    let position = (0..m).map(|i| [0.08 * r[i], 0.08 * r[m + i]]).collect();
    let velocity = (0..m)
        .map(|i| {
            if i % 4 == 0 {
                [0.0, 0.0]
            } else {
                [0.1 * r[2 * m + i], 0.1 * r[3 * m + i]]
            }
        })
        .collect();
    let mu = (0..m)
        .map(|i| 0.2 + 0.02 * (i % 5) as f64)
        .collect::<Vec<_>>();
    let mu_s = mu.iter().map(|u| u + 0.1).collect();
    Parts::points(position, velocity, mu, mu_s)
}

#[test]
fn small_worlds_in_a_batch_are_bitwise_each_world_alone() {
    // 5000 steps: more than one block; parts leave a 0.17 m plate; every 7th step recorded.
    let cfg = config(1.0 / 35.0 / 100.0, 5000.0 / 3500.0, Some(0.17), 7);
    // (worlds of up to 4 points: several sets of eight worlds to a group, a tile's vectors
    // reading different sets' velocities; the last group part empty)
    for (m, b) in [
        (1, 3),
        (2, 33),
        (3, 37),
        (4, 18),
        (5, 9),
        (8, 17),
        (11, 5),
        (30, 3),
    ] {
        let (motions, parts) = (motions(b), parts(m));
        let batch = simulate_batch(&motions, &parts, &cfg).unwrap();
        let mut left = 0;
        for (w, motion) in motions.iter().enumerate() {
            let alone = simulate(motion, &parts, &cfg).unwrap();
            assert_eq!(batch[w], alone, "{m} parts, world {w} of {b}");
            left += alone
                .left_plate
                .iter()
                .flatten()
                .filter(|&&t| t > 0.0)
                .count();
        }
        assert!(
            m < 5 || left > 0,
            "{m} parts: some should leave the plate during the run"
        );
    }
}

/// Enveloped pulses of three timings, interleaved: jets at 50 Hz and 40 Hz, rotations at 50 Hz
/// (each kind at many places and in many directions), and a program of a jet then a rotation.
fn pulses(b: usize) -> Vec<PlateMotion> {
    let r = noise(7 + b as u64, 4 * b);
    (0..b)
        .map(|w| {
            let c = [0.05 * r[4 * w], 0.05 * r[4 * w + 1]];
            let a = std::f64::consts::TAU * r[4 * w + 2];
            let jet = |f: f64| {
                PlateMotion::jet(c, [a.cos(), a.sin()], 0.06, 0.3 + 0.05 * r[4 * w + 3], f)
                    .unwrap()
                    .with_envelope(0.06, 0.05, 0.06)
                    .unwrap()
            };
            let wave: Waveform = Harmonics::new(vec![0.0], vec![0.4 * r[4 * w + 3], 0.1], 50.0)
                .unwrap()
                .into();
            let rotation = PlateMotion::rotation(c, wave)
                .unwrap()
                .with_envelope(0.06, 0.05, 0.06)
                .unwrap();
            match w % 4 {
                0 => jet(50.0),
                1 => rotation,
                2 => jet(40.0),
                _ => PlateMotion::sequence(vec![jet(50.0), rotation]).unwrap(),
            }
        })
        .collect()
}

#[test]
fn pulses_sharing_their_timing_in_a_batch_are_bitwise_each_alone() {
    // Worlds whose pulses share frequency and envelope run in the same groups, which turn their
    // phasors once; the others beside them keep their own. 35 worlds of 8 points: three timings
    // of 9 worlds span two groups of 8 each (their samples taken once for the batch), the fourth
    // (8 worlds) is sampled by its groups. A group of eight jets of one timing has the kernel
    // evaluate them (AVX-512) until the program ends (0.17 s: the plate then rests, and the
    // table takes over); worlds of 3 points (two sets of worlds to a group) read the table.
    // With and without a plate edge, 1 to 2 register tiles a group.
    let b = 35;
    for (m, plate) in [(8, Some(0.2)), (12, None), (5, Some(0.2)), (3, None)] {
        let cfg = config(1.0 / 50.0 / 48.0, 0.4, plate, 5);
        let (motions, parts) = (pulses(b), parts(m));
        let batch = simulate_batch(&motions, &parts, &cfg).unwrap();
        for (w, motion) in motions.iter().enumerate() {
            let alone = simulate(motion, &parts, &cfg).unwrap();
            assert_eq!(batch[w], alone, "{m} points, world {w} of {b}");
        }
        let moved = batch
            .iter()
            .all(|r| r.positions.last() != parts.position.last());
        assert!(moved, "{m} points: every pulse moves the parts");
    }
}

#[test]
fn jets_of_one_timing_in_worlds_of_a_few_points_are_bitwise_each_alone() {
    // Worlds of 1 to 4 points take several sets of eight worlds to a group (one group of 21
    // worlds of 1 or 2 points, with absent sets; two groups of 3 or 4 points): under jets of one
    // timing the AVX-512 kernel evaluates each set's velocity for its vectors, the other builds
    // read the table.
    let motions: Vec<PlateMotion> = pulses(84).into_iter().step_by(4).collect(); // 50 Hz jets
    for (m, plate) in [(1, Some(0.2)), (2, None), (3, Some(0.2)), (4, None)] {
        let cfg = config(1.0 / 50.0 / 48.0, 0.25, plate, 11);
        let parts = parts(m);
        let batch = simulate_batch(&motions, &parts, &cfg).unwrap();
        for (w, motion) in motions.iter().enumerate() {
            let alone = simulate(motion, &parts, &cfg).unwrap();
            assert_eq!(batch[w], alone, "{m} points, world {w}");
            assert_ne!(
                alone.positions.last(),
                parts.position.last(),
                "{m}: {w} moves"
            );
        }
    }
}

/// Runs `motions` on `parts` in one batch, each world with its own friction (a row of `m`
/// values each) and, with `moved`, its own start (the parts shifted by a world's own offset), and
/// checks each world against it run alone with its rows; returns how many of its parts left the
/// plate.
fn each_alone_with_its_rows(
    motions: &[PlateMotion],
    parts: &Parts,
    cfg: &Config,
    moved: bool,
) -> usize {
    let (b, m) = (motions.len(), parts.position.len());
    let mu: Vec<f64> = (0..b * m).map(|k| 0.15 + 0.01 * (k % 13) as f64).collect();
    let mu_s: Vec<f64> = mu.iter().map(|u| u * 1.3).collect();
    let start: Vec<[f64; 2]> = (0..b * m)
        .map(|k| {
            let p = parts.position[k % m];
            let w = (k / m) as f64;
            [p[0] + 0.003 * w, p[1] - 0.002 * (w % 5.0)]
        })
        .collect();
    let friction = WorldRows {
        mu: &mu,
        mu_s: &mu_s,
        width: m,
        position: moved.then_some(&start[..]),
        angle: None,
    };
    let all = simulate_stacked(motions, &parts.view(), cfg, None, Some(&friction), |_| {
        Ok::<(), Error>(())
    })
    .unwrap();
    let rows = all.t.len();
    let mut left = 0;
    for (w, motion) in motions.iter().enumerate() {
        let own = Parts {
            mu: mu[w * m..(w + 1) * m].to_vec(),
            mu_s: mu_s[w * m..(w + 1) * m].to_vec(),
            position: if moved {
                start[w * m..(w + 1) * m].to_vec()
            } else {
                parts.position.clone()
            },
            ..parts.clone()
        };
        let alone = simulate(motion, &own, cfg).unwrap();
        let cells = w * rows * m..(w + 1) * rows * m;
        let at = format!("{m} points, world {w}");
        assert_eq!(all.positions[cells.clone()], alone.positions[..], "{at}");
        assert_eq!(all.velocities[cells.clone()], alone.velocities[..], "{at}");
        assert_eq!(all.stuck[cells], alone.stuck[..], "{at}");
        let gone: Vec<Option<f64>> = (0..m)
            .map(|i| all.left_plate[w * m + i].then_some(all.left[w * m + i]))
            .collect();
        assert_eq!(gone, alone.left_plate, "{at}");
        left += gone.iter().flatten().count();
    }
    left
}

#[test]
fn each_world_of_a_batch_keeps_its_own_friction() {
    let cfg = config(1.0 / 35.0 / 100.0, 0.3, None, 10);
    each_alone_with_its_rows(&motions(10), &parts(6), &cfg, false);
}

#[test]
fn each_world_of_a_batch_starts_from_its_own_layout() {
    // (a vector of environments): grouped points, ungrouped ones with a plate edge, and disks
    let cfg = config(1.0 / 35.0 / 100.0, 0.3, Some(0.4), 10);
    each_alone_with_its_rows(&motions(19), &parts(6), &cfg, true);
    each_alone_with_its_rows(&motions(3), &parts(40), &cfg, true);
}

#[test]
fn a_result_larger_than_the_caches_holds_what_a_small_run_of_its_parts_gives() {
    // 300,000 parts x 3 rows: 29 MB of positions and velocities, written with non-temporal
    // stores; the first and last 500 parts alone make a small result, written plainly.
    let cfg = config(1e-4, 4e-4, Some(0.3), 2);
    let motion = &motions(2)[0];
    let n = 300_000;
    let big = parts(n);
    let all = simulate(motion, &big, &cfg).unwrap();
    let rows = all.t.len();
    assert_eq!(rows, 3);
    for range in [0..500, n - 500..n] {
        let some = Parts::points(
            big.position[range.clone()].to_vec(),
            big.velocity[range.clone()].to_vec(),
            big.mu[range.clone()].to_vec(),
            big.mu_s[range.clone()].to_vec(),
        );
        let small = simulate(motion, &some, &cfg).unwrap();
        for r in 0..rows {
            let cells = r * n + range.start..r * n + range.end;
            assert_eq!(
                all.positions[cells.clone()],
                small.positions[r * 500..(r + 1) * 500]
            );
            assert_eq!(
                all.velocities[cells.clone()],
                small.velocities[r * 500..(r + 1) * 500]
            );
            assert_eq!(all.stuck[cells], small.stuck[r * 500..(r + 1) * 500]);
        }
        assert_eq!(all.left_plate[range], small.left_plate[..]);
    }
}

#[test]
fn little_work_counts_point_steps_with_a_disk_as_64_points_and_a_polygon_as_ten_disks() {
    // Under 65,536 point-steps is little work (run on the calling thread alone).
    let cfg = |steps: usize| config(1e-4, steps as f64 * 1e-4, None, 1);
    let points = |m: usize| {
        Parts::points(
            vec![[0.0; 2]; m],
            vec![[0.0; 2]; m],
            vec![0.3; m],
            vec![0.4; m],
        )
    };
    let little = |worlds: usize, parts: &Parts, steps: usize| {
        little_work(worlds, &parts.view(), &cfg(steps))
    };
    assert!(little(20, &points(8), 100)); // 16,000
    assert!(little(1, &points(65), 1000)); // 65,000
    assert!(!little(1, &points(66), 1000)); // 66,000
    assert!(!little(20, &points(8), 1000)); // 160,000
    let mut disks = points(3);
    disks.radius = vec![0.005, 0.0, 0.0]; // one disk and two points: 66 a step
    assert!(little(1, &disks, 990)); // 65,340
    assert!(!little(1, &disks, 1000)); // 66,000
    let mut polygon = points(1);
    let square = [
        [-0.005, -0.005],
        [0.005, -0.005],
        [0.005, 0.005],
        [-0.005, 0.005],
    ];
    polygon.polygons = vec![(
        0,
        upm_core::polygon::Polygon::new("square", &square).unwrap(),
    )];
    assert!(little(1, &polygon, 100)); // 64,000
    assert!(!little(1, &polygon, 103)); // 65,920
                                        // Settings a run rejects count as little (the run fails at once).
    let mut bad = cfg(100);
    bad.dt = f64::NAN;
    assert!(little_work(1, &points(8).view(), &bad));
    bad.dt = 0.0;
    assert!(little_work(1, &points(8).view(), &bad));
}

#[test]
fn worlds_beyond_a_group_share_their_timings_samples_bitwise() {
    // Worlds of 40 points (more than a group takes), and worlds of points and disks, run one by
    // one; those of one timing evaluate their plate velocity from samples taken once for them
    // all, block by block (two blocks here). Pulses of four timings interleaved with harmonic
    // rotations and translations of a fifth.
    let cfg = config(1.0 / 50.0 / 48.0, 5000.0 / 2400.0, Some(0.2), 9);
    let mut motions = pulses(12);
    motions.extend(self::motions(6));
    let mut mixed = parts(9);
    mixed.radius = (0..9)
        .map(|i| if i % 3 == 0 { 0.004 } else { 0.0 })
        .collect();
    mixed.angle = vec![0.0; 9];
    mixed.spin = (0..9).map(|i| 3.0 * (i as f64 - 4.0)).collect();
    for parts in [parts(40), mixed] {
        let batch = simulate_batch(&motions, &parts, &cfg).unwrap();
        for (w, motion) in motions.iter().enumerate() {
            let alone = simulate(motion, &parts, &cfg).unwrap();
            assert_eq!(batch[w], alone, "{} parts, world {w}", parts.position.len());
        }
    }
}

#[test]
fn groups_of_whole_vectors_in_one_block_are_bitwise_each_world_alone() {
    // Worlds of 8, 16 and 24 points (one, two and three whole vectors each) through one block,
    // with friction per world, parts leaving the plate, every 7th step recorded.
    let cfg = config(1.0 / 35.0 / 100.0, 0.6, Some(0.12), 7);
    for (m, b) in [(8, 11), (16, 7), (24, 5)] {
        let left = each_alone_with_its_rows(&motions(b), &parts(m), &cfg, false);
        assert!(left > 0, "{m} points: some leave the plate");
    }
    // A state that is not finite is named, as in any run.
    let mut bad = parts(16);
    bad.position[11][1] = f64::NAN;
    let err = simulate_batch(&motions(3), &bad, &cfg).unwrap_err();
    assert!(err.to_string().contains("11"), "{err}");
}

#[test]
fn parts_start_stuck_in_just_the_worlds_whose_plate_they_move_with() {
    // Worlds that share their parts read them once a group, but whether a part starts stuck
    // depends on each world's plate velocity at the start: each part here but the last moves
    // with one world's plate surface; the last starts off the plate.
    let cfg = config(1.0 / 35.0 / 100.0, 0.2, Some(0.17), 9);
    for (m, b) in [(3, 21), (8, 13)] {
        let motions = motions(b);
        let mut parts = parts(m);
        parts.position[m - 1] = [0.2, 0.0];
        let with = |i: usize| (2 * i + 1) % b; // the world part i moves with
        for i in 0..m - 1 {
            let u = motions[with(i)].velocity(0.0);
            let [x, y] = parts.position[i];
            parts.velocity[i] = [u[0] - u[2] * y, u[1] + u[2] * x];
        }
        let batch = simulate_batch(&motions, &parts, &cfg).unwrap();
        for (w, motion) in motions.iter().enumerate() {
            let alone = simulate(motion, &parts, &cfg).unwrap();
            assert_eq!(batch[w], alone, "{m} parts, world {w} of {b}");
            for i in 0..m - 1 {
                let stuck = alone.stuck[i];
                assert_eq!(stuck, w == with(i), "{m} parts: part {i} in world {w}");
            }
            assert_eq!(alone.left_plate[m - 1], Some(0.0), "{m} parts, world {w}");
        }
    }
}
