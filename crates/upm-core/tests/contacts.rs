//! Disk contacts through rapier2d against laws independent of the code: momentum, restitution,
//! non-penetration, walls, and the contact-free integrator for parts that never touch.

use upm_core::motion::PlateMotion;
use upm_core::sim::{simulate_worlds_with, Config, Contacts, Parts, Trajectory};
use upm_core::{Error, Harmonics, Waveform};

fn disks(position: Vec<[f64; 2]>, velocity: Vec<[f64; 2]>, radius: Vec<f64>, mu: f64) -> Parts {
    let m = position.len();
    Parts {
        position,
        velocity,
        mu: vec![mu; m],
        mu_s: vec![mu; m],
        radius,
        angle: vec![0.0; m],
        spin: vec![0.0; m],
        polygons: Vec::new(),
    }
}

fn cfg(dt: f64, duration: f64) -> Config {
    Config {
        dt,
        duration,
        g: 9.81,
        plate_size: None,
        record_every: 1,
        tilt: [0.0; 2],
    }
}

fn run(
    motion: &PlateMotion,
    parts: &Parts,
    cfg: &Config,
    contacts: Option<&Contacts>,
) -> Result<Trajectory, Error> {
    let mut r = simulate_worlds_with(
        std::slice::from_ref(motion),
        &parts.view(),
        cfg,
        contacts,
        |_| Ok::<(), Error>(()),
    )?;
    Ok(r.remove(0))
}

fn row<T: Copy>(a: &[T], m: usize, r: usize) -> &[T] {
    &a[r * m..(r + 1) * m]
}

#[test]
fn a_head_on_collision_conserves_momentum_and_follows_the_restitution_coefficient() {
    // Next to no plate friction (mu = 1e-12): before and after the impact the velocities are
    // constant, so momentum and the restitution law can be read off directly.
    let still = PlateMotion::rest(1.0).unwrap();
    let (ma, mb) = (1.0, 3.0);
    let (va, vb) = (0.2, -0.1);
    for e in [0.0, 0.5, 0.9] {
        let parts = disks(
            vec![[-0.02, 0.0], [0.02, 0.0]],
            vec![[va, 0.0], [vb, 0.0]],
            vec![0.01, 0.01],
            1e-12,
        );
        let c = Contacts {
            restitution: e,
            part_friction: 0.0,
            mass: Some(vec![ma, mb]),
            ..Contacts::default()
        };
        let tr = run(&still, &parts, &cfg(1e-4, 0.3), Some(&c)).unwrap();
        let end = tr.t.len() - 1;
        let v = row(&tr.velocities, 2, end);
        let p0 = ma * va + mb * vb;
        let p1 = ma * v[0][0] + mb * v[1][0];
        assert!((p1 - p0).abs() < 1e-9, "e = {e}: momentum {p0} -> {p1}");
        let sep = v[1][0] - v[0][0];
        let want = e * (va - vb);
        assert!(
            (sep - want).abs() < 0.02 * (va - vb),
            "e = {e}: separation speed {sep}, want {want}"
        );
        assert!(v[0][1].abs() < 1e-12 && v[1][1].abs() < 1e-12);
        // Never more than 1% of a radius of overlap on the way.
        for r in 0..tr.t.len() {
            let p = row(&tr.positions, 2, r);
            let gap = (p[1][0] - p[0][0]).hypot(p[1][1] - p[0][1]) - 0.02;
            assert!(
                gap > -1e-4,
                "e = {e}: overlap {} m at t = {}",
                -gap,
                tr.t[r]
            );
        }
    }
}

#[test]
fn disks_that_never_touch_move_exactly_as_without_contacts() {
    let wave: Waveform = Harmonics::new(vec![2.0, -1.0], vec![], 35.0)
        .unwrap()
        .into();
    let spin = PlateMotion::rotation([0.0, 0.0], wave).unwrap();
    let parts = disks(
        vec![[0.05, 0.0], [-0.05, 0.02], [0.0, -0.08]],
        vec![[0.0; 2]; 3],
        vec![0.01, 0.008, 0.012],
        0.3,
    );
    let c = cfg(1e-4, 0.2);
    let free = run(&spin, &parts, &c, None).unwrap();
    let with = run(&spin, &parts, &c, Some(&Contacts::default())).unwrap();
    for (a, b) in free.positions.iter().zip(&with.positions) {
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
    }
    assert_eq!(free.stuck, with.stuck);
}

#[test]
fn a_disk_pushed_against_a_wall_stops_at_it() {
    // A translating plate with the asymmetric drive feeds the disk along +x into a fence at
    // x = 0.03: its centre must stop one radius short of it, and stay there: each half period
    // T / 2 that the plate pulls away it drags the disk back by at most mu g (T / 2)^2 / 2.
    let wave: Waveform = Harmonics::new(vec![0.1, -0.05], vec![], 35.0)
        .unwrap()
        .into();
    let feed = PlateMotion::translation([1.0, 0.0], wave).unwrap();
    let r = 0.01;
    let parts = disks(vec![[0.0, 0.0]], vec![[0.0; 2]], vec![r], 0.3);
    let c = Contacts {
        walls: vec![[[0.03, -0.1], [0.03, 0.1]]],
        restitution: 0.0,
        ..Contacts::default()
    };
    let tr = run(&feed, &parts, &cfg(1e-4, 2.0), Some(&c)).unwrap();
    let free = run(&feed, &parts, &cfg(1e-4, 2.0), None).unwrap();
    let x_free = free.positions.last().unwrap()[0];
    assert!(
        x_free > 0.05,
        "the drive must feed past the wall without it: {x_free}"
    );
    let x_max = tr.positions.iter().map(|p| p[0]).fold(f64::MIN, f64::max);
    let late = &tr.positions[tr.positions.len() / 2..];
    let x_min = late.iter().map(|p| p[0]).fold(f64::MAX, f64::min);
    assert!(x_max < 0.03 - r + 0.01 * r, "overshoot: {x_max}");
    let pull = 0.3 * 9.81 * (0.5 / 35.0f64).powi(2) / 2.0;
    assert!(
        x_min > 0.03 - r - pull,
        "the disk should stay at the wall: {x_min}"
    );
}

#[test]
fn contacts_are_identical_run_to_run_and_for_any_thread_count() {
    let wave: Waveform = Harmonics::new(vec![2.0, -1.0], vec![], 35.0)
        .unwrap()
        .into();
    let motions = vec![
        PlateMotion::rotation([0.0, 0.0], wave.clone()).unwrap(),
        PlateMotion::rotation([0.02, 0.01], wave).unwrap(),
    ];
    let position: Vec<[f64; 2]> = (0..12)
        .map(|i| [0.021 * (i % 4) as f64 - 0.03, 0.021 * (i / 4) as f64 - 0.02])
        .collect();
    let parts = disks(position, vec![[0.0; 2]; 12], vec![0.01; 12], 0.3);
    let c = cfg(1e-4, 0.1);
    let go = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                simulate_worlds_with(
                    &motions,
                    &parts.view(),
                    &c,
                    Some(&Contacts::default()),
                    |_| Ok::<(), Error>(()),
                )
                .unwrap()
            })
    };
    let one = go(1);
    assert_eq!(one, go(2));
    assert_eq!(one, go(1));
}

#[test]
fn bad_contact_settings_and_overlapping_disks_are_refused() {
    let still = PlateMotion::rest(1.0).unwrap();
    let c = cfg(1e-4, 0.01);
    let ok = disks(
        vec![[0.0, 0.0], [0.05, 0.0]],
        vec![[0.0; 2]; 2],
        vec![0.01; 2],
        0.3,
    );
    let overlap = disks(
        vec![[0.0, 0.0], [0.015, 0.0]],
        vec![[0.0; 2]; 2],
        vec![0.01; 2],
        0.3,
    );
    let msg = |p: &Parts, k: &Contacts| run(&still, p, &c, Some(k)).unwrap_err().to_string();
    assert!(msg(&overlap, &Contacts::default()).contains("disks 0 and 1 overlap"));
    // Without contacts, overlapping disks simply pass through each other.
    assert!(run(&still, &overlap, &c, None).is_ok());
    let bad = |k: Contacts, word: &str| {
        let m = msg(&ok, &k);
        assert!(m.starts_with(word), "{m}");
    };
    bad(
        Contacts {
            restitution: 1.5,
            ..Contacts::default()
        },
        "restitution",
    );
    bad(
        Contacts {
            part_friction: f64::NAN,
            ..Contacts::default()
        },
        "part_friction",
    );
    bad(
        Contacts {
            walls: vec![[[0.0, -1.0], [0.0, 1.0]]],
            ..Contacts::default()
        },
        "walls",
    );
    bad(
        Contacts {
            mass: Some(vec![1.0, -1.0]),
            ..Contacts::default()
        },
        "mass",
    );
}

#[test]
fn disks_fed_into_each_other_against_a_wall_never_overlap_beyond_a_percent_of_a_radius() {
    // Five disks in a row fed along +x into a fence: they pile up and press on each other for
    // a second of shaking at 35 Hz.
    let wave: Waveform = Harmonics::new(vec![0.1, -0.05], vec![], 35.0)
        .unwrap()
        .into();
    let feed = PlateMotion::translation([1.0, 0.0], wave).unwrap();
    let r = 0.005;
    let position: Vec<[f64; 2]> = (0..5)
        .map(|i| [-0.06 + 0.015 * i as f64, 0.001 * i as f64])
        .collect();
    let parts = disks(position, vec![[0.0; 2]; 5], vec![r; 5], 0.3);
    let c = Contacts {
        walls: vec![[[0.03, -0.1], [0.03, 0.1]]],
        ..Contacts::default()
    };
    let tr = run(&feed, &parts, &cfg(1e-4, 1.5), Some(&c)).unwrap();
    let mut worst: f64 = 0.0;
    for k in 0..tr.t.len() {
        let p = row(&tr.positions, 5, k);
        for i in 0..5 {
            worst = worst.max(p[i][0] + r - 0.03);
            for j in i + 1..5 {
                worst = worst.max(2.0 * r - (p[i][0] - p[j][0]).hypot(p[i][1] - p[j][1]));
            }
        }
    }
    assert!(worst < 0.01 * r, "largest overlap {worst} m");
    // They did pile up: the last one sits within a few radii of the wall's pile.
    let end = row(&tr.positions, 5, tr.t.len() - 1);
    let x_first = end.iter().map(|p| p[0]).fold(f64::MAX, f64::min);
    assert!(
        x_first > 0.03 - 12.0 * r,
        "the row did not reach the wall: {x_first}"
    );
}
