//! The meshless solver (seed 004) against its published references.

use vademecum_engine::material::LinearElastic;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::meshless::efg::{self, AdrParams, EfgProblem};
use vademecum_engine::meshless::grid::box_grid;
use vademecum_engine::meshless::mls::NodeCloud;

/// Seed 004 Table 3.2: a 0.1 m square, plane strain, edge x = 0 clamped, edge x = 0.1 m pulled
/// by `stretch × 0.1` m in x with its y motion fixed.
fn square(n: usize, stretch: f64) -> (f64, f64, usize) {
    let h = 0.1 / (n - 1) as f64;
    let mut pts = Vec::new();
    for j in 0..n {
        for i in 0..n {
            pts.push([i as f64 * h, j as f64 * h, 0.0]);
        }
    }
    let cloud = NodeCloud::new(2, pts.clone(), vec![2.2 * h; pts.len()]);
    let points = box_grid(2, [0.0; 3], [0.1, 0.1, 0.0], [n - 1, n - 1, 1], |_| true);
    let mut prescribed = Vec::new();
    for (i, p) in pts.iter().enumerate() {
        if p[0].abs() < 1e-12 {
            prescribed.push((i, 0, 0.0));
            prescribed.push((i, 1, 0.0));
        } else if (p[0] - 0.1).abs() < 1e-12 {
            prescribed.push((i, 0, 0.1 * stretch));
            prescribed.push((i, 1, 0.0));
        }
    }
    let problem = EfgProblem {
        cloud,
        points,
        law: Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, 0.49).unwrap()),
        prescribed: prescribed.clone(),
    };
    let s = efg::solve(&problem, &AdrParams::default(), |step, e| eprintln!("step {step}: error {e:.3e}")).unwrap();
    let force: f64 = prescribed
        .iter()
        .zip(&s.reactions)
        .filter(|((i, k, _), _)| *k == 0 && (pts[*i][0] - 0.1).abs() < 1e-12)
        .map(|(_, r)| r)
        .sum();
    (s.energy, force, s.steps)
}

#[test]
fn the_2d_square_matches_table_3_2() {
    let (e, f, steps) = square(21, 0.2);
    eprintln!("21 x 21: W = {e:.4} J, F = {f:.3} N, {steps} steps");
    assert!((e - 0.847).abs() < 0.01 * 0.847, "energy {e}");
    assert!((f - 77.64).abs() < 0.01 * 77.64, "force {f}");
}
