use super::*;
use crate::geometry::vec3::{dot, sub};
use crate::mesh::boundary::Boundary;
use crate::mesh::procedural;

fn lobe() -> (Vec<[f64; 3]>, Surface, Bounds) {
    let mesh = procedural::lobe(&procedural::LobeParams::default());
    let tris = Boundary::of(&mesh).triangles();
    let bounds = Bounds::of(&mesh.nodes, &tris);
    let s = Surface::new(&mesh.nodes, tris);
    (mesh.nodes, s, bounds)
}

use crate::rng::Rng;

fn scan(s: &Surface, p: [f64; 3]) -> (f64, SurfacePoint) {
    (0..s.len())
        .map(|t| {
            let q = s.closest_on(t, p);
            (dot(sub(p, q.point), sub(p, q.point)), q)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap()
}

/// Crossings of the ray from `p` along a fixed odd direction (parity: inside when odd).
fn ray_inside(s: &Surface, nodes: &[[f64; 3]], p: [f64; 3]) -> bool {
    let d = [0.5773, 0.5774, 0.5772];
    let mut hits = 0;
    for t in s.triangles() {
        let (a, b, c) = (nodes[t[0]], nodes[t[1]], nodes[t[2]]);
        let (e1, e2) = (sub(b, a), sub(c, a));
        let h = [
            d[1] * e2[2] - d[2] * e2[1],
            d[2] * e2[0] - d[0] * e2[2],
            d[0] * e2[1] - d[1] * e2[0],
        ];
        let det = dot(e1, h);
        if det.abs() < 1e-18 {
            continue;
        }
        let sv = sub(p, a);
        let u = dot(sv, h) / det;
        let q = [
            sv[1] * e1[2] - sv[2] * e1[1],
            sv[2] * e1[0] - sv[0] * e1[2],
            sv[0] * e1[1] - sv[1] * e1[0],
        ];
        let v = dot(d, q) / det;
        let tt = dot(e2, q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt > 0.0 {
            hits += 1;
        }
    }
    hits % 2 == 1
}

/// The grid searches find exactly what a scan over every triangle finds.
#[test]
fn grid_searches_match_a_full_scan() {
    let (nodes, s, _) = lobe();
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let mut found = 0;
    for i in 0..5_000 {
        let p = nodes[(rng.unit() * nodes.len() as f64) as usize % nodes.len()];
        let tip = [0, 1, 2].map(|k| p[k] + 0.03 * (rng.unit() - 0.5));
        let reach = 0.002 + 0.008 * rng.unit();
        let (d2, best) = scan(&s, tip);
        match s.nearest_within(tip, reach) {
            Some(q) => {
                let e = dot(sub(tip, q.point), sub(tip, q.point));
                assert!((e - d2).abs() <= 1e-15, "{i}: {e} vs {d2}");
                found += 1;
            }
            None => assert!(d2.sqrt() > reach * (1.0 - 1e-12), "{i}: missed a triangle at {}", d2.sqrt()),
        }
        if let Some(q) = s.nearest(tip) {
            let e = dot(sub(tip, q.point), sub(tip, q.point));
            assert!((e - d2).abs() <= 1e-15, "{i}: nearest {e} vs scan {d2} ({best:?})");
        }
    }
    assert!(found > 500, "the sample should often be near the surface ({found})");
}

/// Inside or outside, by the grid classes and pseudo-normals, agrees with ray parity.
#[test]
fn inside_agrees_with_ray_parity() {
    let (nodes, s, b) = lobe();
    let mut rng = Rng(7);
    let mut inside = 0;
    for _ in 0..3_000 {
        let p = [0, 1, 2].map(|k| b.min[k] - 0.01 + (b.max[k] - b.min[k] + 0.02) * rng.unit());
        let expect = ray_inside(&s, &nodes, p);
        assert_eq!(s.contains(p), expect, "{p:?}");
        inside += usize::from(expect);
    }
    assert!(inside > 300, "{inside}");
}

/// The lobe's top (z = max) near its middle, and the probe radius used below.
fn top_point(b: &Bounds, fx: f64, fy: f64) -> [f64; 3] {
    [
        b.min[0] + fx * (b.max[0] - b.min[0]),
        b.min[1] + fy * (b.max[1] - b.min[1]),
        b.max[2] + 0.01,
    ]
}

/// Pressing straight down far beyond the tip's radius keeps the contact, with a depth that
/// grows with every step and equals how far the tip went in — while the tip is inside. Pressed
/// on through the lobe and out of its underside, the tip is touched by the underside alone
/// (never deeper than r), and released once its sphere is clear of it.
#[test]
fn a_deep_press_never_lets_go() {
    let (_, s, b) = lobe();
    let r = 0.004;
    for (fx, fy) in [(0.5, 0.5), (0.3, 0.6), (0.7, 0.4), (0.45, 0.55)] {
        let start = top_point(&b, fx, fy);
        let mut proxy = Proxy::default();
        let (mut last, mut deepest, mut touched_at, mut out_below) = (0.0, 0.0_f64, None, None);
        for i in 0..=8000 {
            let tip = [start[0], start[1], start[2] - 1e-5 * i as f64];
            let inside = s.contains(tip);
            if touched_at.is_some() && !inside && tip[2] < start[2] - 0.02 {
                out_below.get_or_insert(i);
            }
            match proxy.update(&s, &b, tip, r) {
                Some(t) if out_below.is_none() => {
                    touched_at.get_or_insert(i);
                    assert!(t.depth > last, "depth must grow: {} after {last} at step {i}", t.depth);
                    last = t.depth;
                    deepest = deepest.max(t.depth);
                }
                Some(t) => {
                    assert!(t.depth <= r, "out of the underside, the tip still feels {} m at step {i}", t.depth);
                    assert!(t.normal[2] < 0.0, "out of the underside, touched by {:?}", t.normal);
                }
                None => assert!(
                    touched_at.is_none() || out_below.is_some(),
                    "lost the contact at step {i} (depth {last})"
                ),
            }
        }
        // 80 mm down from above the organ: more than 5 radii deep (past the middle of the lobe,
        // where the far side is nearer than the side it entered through), then out below
        assert!(touched_at.is_some() && out_below.is_some());
        assert!(deepest > 5.0 * r, "{deepest}");
        assert_eq!(proxy.update(&s, &b, [start[0], start[1], start[2] - 0.08], r), None);
    }
}

/// Largest change of a quantity between consecutive samples of a path.
fn max_jump(samples: &[[f64; 4]]) -> f64 {
    samples
        .windows(2)
        .map(|w| (0..4).map(|k| (w[1][k] - w[0][k]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max)
}

/// Sliding while pressed deep, across triangle edges and vertices: depth and normal change
/// continuously (halving the step halves the largest change, which a jump would not).
#[test]
fn a_lateral_sweep_while_pressed_has_no_jumps() {
    let (_, s, b) = lobe();
    let r = 0.004;
    let sweep = |n: usize| {
        let mut proxy = Proxy::default();
        let a = top_point(&b, 0.25, 0.3);
        // come down until touching, then 8 mm (2 radii) further, then slide diagonally
        // (crossing edges and vertices)
        let mut z = a[2];
        while proxy.update(&s, &b, [a[0], a[1], z], r).is_none() {
            z -= 1e-5;
        }
        for _ in 0..800 {
            z -= 1e-5;
            proxy.update(&s, &b, [a[0], a[1], z], r);
        }
        let mut out = Vec::new();
        for i in 0..=n {
            let u = i as f64 / n as f64;
            let tip = [a[0] + u * 0.5 * (b.max[0] - b.min[0]), a[1] + u * 0.4 * (b.max[1] - b.min[1]), z];
            let t = proxy.update(&s, &b, tip, r).expect("stays in contact");
            out.push([t.depth, t.normal[0] * r, t.normal[1] * r, t.normal[2] * r]);
        }
        max_jump(&out)
    };
    let (coarse, fine) = (sweep(2000), sweep(4000));
    assert!(fine < 0.7 * coarse, "no jumps: largest change {coarse} at n, {fine} at 2n");
    assert!(coarse < 1e-4, "{coarse}");
}

/// The tip comes at the organ from every side (faces, an edge, a corner, the bottom): the
/// contact starts at the surface with a small depth and holds all the way to the centre.
#[test]
fn entering_from_any_side_holds_to_the_centre() {
    let (_, s, b) = lobe();
    let r = 0.003;
    let centre = [0, 1, 2].map(|k| 0.5 * (b.min[k] + b.max[k]));
    let dirs: [[f64; 3]; 9] = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 1.0],
        [-1.0, 1.0, 0.0],
        [1.0, 1.0, -1.0],
    ];
    for d in dirs {
        let l = dot(d, d).sqrt();
        let d = d.map(|x| x / l);
        let far = 0.2;
        let mut proxy = Proxy::default();
        let mut first = None;
        let n = 20_000;
        for i in 0..=n {
            let u = far * (1.0 - i as f64 / n as f64);
            let tip = [0, 1, 2].map(|k| centre[k] + u * d[k]);
            match proxy.update(&s, &b, tip, r) {
                Some(t) => {
                    if first.is_none() {
                        first = Some(t.depth);
                        assert!(!s.contains(tip), "touched only once inside, from {d:?}");
                    }
                }
                None => assert!(first.is_none(), "lost the contact from {d:?} at u = {u}"),
            }
        }
        assert!(first.expect("touched") < 2.0 * far / n as f64 + 1e-12, "from {d:?}: {first:?}");
    }
}

/// A tool that appears inside (no history) gets the nearest surface at once; one beyond the
/// organ's box is released; NaN is no contact.
#[test]
fn a_tool_that_appears_inside_is_in_contact_at_once() {
    let (_, s, b) = lobe();
    let centre = [0, 1, 2].map(|k| 0.5 * (b.min[k] + b.max[k]));
    let mut p = Proxy::default();
    let t = p.update(&s, &b, centre, 0.004).expect("inside");
    assert!(t.depth > 0.004);
    assert!(p.update(&s, &b, [centre[0], centre[1], b.max[2] + 0.5], 0.004).is_none());
    assert!(!p.in_contact());
    assert!(p.update(&s, &b, [f64::NAN, 0.0, 0.0], 0.004).is_none());
}
