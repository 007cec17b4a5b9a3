//! Tests of the friction in lanes ([`super`]).
use super::super::lanes::tests::{centres, outlines};
use super::*;

fn relative(a: f64, b: f64, scale: f64) -> f64 {
    (a - b).abs() / scale
}

fn shapes() -> Vec<Polygon> {
    let [nine, triangle] = outlines();
    let hexagon: Vec<[f64; 2]> = (0..6)
        .map(|k| {
            let a = std::f64::consts::PI * k as f64 / 3.0;
            [0.008 * a.cos(), 0.008 * a.sin()]
        })
        .collect();
    // 20 edges: more than a block of the AVX2 build
    let many: Vec<[f64; 2]> = (0..20)
        .map(|k| {
            let a = std::f64::consts::PI * k as f64 / 10.0;
            [0.01 * a.cos() + 0.002, 0.006 * a.sin()]
        })
        .collect();
    [&nine[..], &triangle[..], &hexagon[..], &many[..]]
        .iter()
        .map(|o| Polygon::new("p", o).unwrap())
        .collect()
}

#[test]
fn lanes_agree_with_the_fan_and_give_a_lane_s_bits_beside_any_others() {
    let all = shapes();
    for (s, p) in all.iter().enumerate() {
        let alone = Quad::of([None, Some(p), None, None]);
        for (i, r0) in centres(p).into_iter().enumerate() {
            let want = p.fan(r0);
            let one = fan_lane(&alone, 1, r0);
            // (the terms' size: the area times the distances)
            let far = p.radius + r0[0].hypot(r0[1]);
            assert!(
                relative(one.dist, want.dist, p.area * far) < 1e-14,
                "shape {s}, centre {i}: {one:?} against {want:?}"
            );
            for j in 0..2 {
                assert!(relative(one.unit[j], want.unit[j], p.area) < 1e-14);
            }
            let g = want.curvature.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
            // (on a vertex an edge's line through it may miss it by a rounding, and its
            // curvature is then not a number: the same in both)
            for j in (0..3).filter(|_| !want.curvature.iter().any(|x| x.is_nan())) {
                assert!(
                    relative(one.curvature[j], want.curvature[j], g) < 1e-13,
                    "shape {s}, centre {i}: {:?} against {:?}",
                    one.curvature,
                    want.curvature
                );
            }
            // the friction of the rotation about r0: in every lane, beside other shapes
            // at other centres (or none), either build, the same bits
            let spin = |r: [f64; 2], omega: f64| [r[1] * omega, -r[0] * omega, omega];
            let twist = spin(r0, -1.7);
            let alone = friction_lane(&alone, 1, twist);
            for lane in 0..FOUR {
                let mut lanes: [Option<&Polygon>; FOUR] =
                    std::array::from_fn(|l| all.get((s + l + 1) % (all.len() + 1)));
                lanes[lane] = Some(p);
                let q = Quad::of(lanes);
                let mut t: [[f64; 3]; FOUR] = std::array::from_fn(|l| {
                    lanes[l].map_or([0.0, 0.0, 1.0], |o| spin(centres(o)[(i + l) % 8], 0.3))
                });
                t[lane] = twist;
                let live = lanes.map(|o| o.is_some());
                let same = |f: Friction| {
                    let bits = |f: Friction| {
                        f.wrench
                            .into_iter()
                            .chain([f.work])
                            .chain(f.hessian.into_iter().flatten())
                            .map(|x| if x.is_nan() { u64::MAX } else { x.to_bits() })
                            .collect::<Vec<_>>()
                    };
                    bits(f) == bits(alone)
                };
                assert!(
                    same(friction_lane(&q, lane, twist)),
                    "shape {s}, centre {i}"
                );
                assert!(
                    same(friction_four(&q, t, live)[lane]),
                    "shape {s}, centre {i}"
                );
                #[cfg(target_arch = "x86_64")]
                if is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let got = unsafe { super::super::avx2::friction_four(&q, t) };
                    assert!(same(got[lane]), "avx2, shape {s}, centre {i}, lane {lane}");
                }
            }
        }
    }
}

#[test]
fn a_quad_makes_room_for_a_polygon_of_more_edges() {
    let all = shapes();
    let (triangle, many) = (&all[1], &all[3]);
    let mut grown = Quad::of([Some(triangle), None, None, None]);
    grown.set(2, Some(many));
    let fresh = Quad::of([Some(triangle), None, Some(many), None]);
    assert_eq!(grown.edges(), many.vertices.len());
    for (l, p) in [(0, triangle), (2, many)] {
        for r0 in centres(p) {
            let (a, b) = (fan_lane(&grown, l, r0), fan_lane(&fresh, l, r0));
            let bits = |f: Fan| [f.dist, f.unit[0], f.curvature[2]].map(f64::to_bits);
            assert_eq!(bits(a), bits(b), "lane {l}");
        }
    }
}

#[test]
fn two_quads_in_lanes_of_eight_give_each_lane_the_bits_of_four() {
    // each lane's evaluation (friction, Phi, Newton step) at centres inside, outside, on
    // edges and at vertices of four shapes, beside other shapes and empty lanes: the
    // AVX-512 build's vectors of eight give the bits of the AVX2 build's four, and of the
    // portable lane
    let all = shapes();
    let lanes = [
        [Some(&all[0]), Some(&all[1]), None, Some(&all[3])],
        [Some(&all[2]), Some(&all[3]), Some(&all[1]), Some(&all[0])],
    ];
    let q = lanes.map(Quad::of);
    assert_eq!(q[0].edges(), q[1].edges());
    let spin = |r: [f64; 2], omega: f64| [r[1] * omega, -r[0] * omega, omega];
    let mut checked = 0;
    for i in 0..8 {
        let asks: [Asked; EIGHT] = std::array::from_fn(|l| {
            let p = lanes[l / FOUR][l % FOUR].unwrap_or(&all[0]);
            let omega = 0.4 + 0.3 * l as f64 - 1.3 * (i % 3) as f64;
            let twist = spin(super::super::lanes::tests::centres(p)[(i + l) % 8], omega);
            Asked {
                twist,
                y: [twist[0] * 1.1, twist[1] - 1e-3, 0.004 * twist[2]],
                target: [0.01 * l as f64, -0.02, 0.003 * i as f64],
                c: 2e-4 * (1.0 + l as f64),
                kinv: 150.0 + 10.0 * l as f64,
            }
        });
        let bits = |e: &Evals, l: usize| -> Vec<u64> {
            let e = e.get(l);
            [e.value, e.gnorm, e.length, e.slope, e.norm]
                .into_iter()
                .chain(e.step)
                .map(|x| if x.is_nan() { u64::MAX } else { x.to_bits() })
                .collect()
        };
        let mut portable = [Evals::default(); 2];
        for l in 0..EIGHT {
            let a = asks[l];
            let f = friction_lane(&q[l / FOUR], l % FOUR, a.twist);
            portable[l / FOUR].set(l % FOUR, &Eval::of(&f, a.y, a.target, a.c, a.kinv));
        }
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            for h in 0..2 {
                let mut four = Evals::default();
                let asks4 = std::array::from_fn(|l| asks[FOUR * h + l]);
                // SAFETY: the CPU has AVX2.
                unsafe { super::super::avx2::evals_four(&q[h], &asks4, &mut four) };
                for l in 0..FOUR {
                    assert_eq!(bits(&four, l), bits(&portable[h], l), "avx2 {i} {h} {l}");
                }
            }
            checked += 1;
        }
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx512f") {
            let mut eight = [Evals::default(); 2];
            // SAFETY: the CPU has AVX-512F.
            unsafe { super::super::avx512::evals_eight([&q[0], &q[1]], &asks, &mut eight) };
            for l in 0..EIGHT {
                let (h, k) = (l / FOUR, l % FOUR);
                assert_eq!(bits(&eight[h], k), bits(&portable[h], k), "avx512 {i} {l}");
            }
            checked += 1;
        }
    }
    // (on a machine without AVX2 there is no vector build to compare)
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        assert!(checked >= 8);
    }
}

#[test]
fn friction_in_lanes_meets_the_one_at_a_time() {
    let all = shapes();
    let mut loaded = all[0].clone();
    loaded.set_load([5.0, -3.0]).unwrap();
    let lanes = [Some(&all[3]), Some(&loaded), Some(&all[1]), Some(&all[2])];
    let q = Quad::of(lanes);
    // near, near (loaded: one at a time), pure translation, pure spin; then far and still
    let sets = [
        [
            [0.01, -0.02, 3.0],
            [0.005, 0.002, 1.0],
            [0.3, -0.1, 0.0],
            [0.0, 0.0, -2.0],
        ],
        [[0.5, 0.2, 1e-3], [-0.004, 0.002, 0.7], [0.0; 3], [0.0; 3]],
    ];
    for (t, live) in sets.iter().zip([[true; 4], [true, true, true, false]]) {
        let got = q.friction_hessian(lanes, *t, live);
        for l in 0..FOUR {
            let p = lanes[l].unwrap();
            let [vx, vy, omega] = t[l];
            let want = if live[l] {
                p.friction_hessian([vx, vy], omega)
            } else {
                Friction::default()
            };
            let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-13 * scale;
            let h = want
                .hessian
                .iter()
                .flatten()
                .fold(0.0, |m: f64, x| m.max(x.abs()));
            for j in 0..3 {
                assert!(close(got[l].wrench[j], want.wrench[j], p.radius), "{l} {j}");
                for k in 0..3 {
                    assert!(close(got[l].hessian[j][k], want.hessian[j][k], h), "{l}");
                }
            }
            assert!(close(got[l].work, want.work, want.work), "{l}");
        }
    }
}
