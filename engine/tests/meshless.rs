//! The meshless solver (seed 004) against its published references.

use vademecum_engine::meshless::efg::{self, AdrParams};
use vademecum_engine::meshless::reference::{self, TABLE_3_2};

#[test]
fn the_2d_square_matches_table_3_2() {
    // one integration point per cell, as the seed
    let case = reference::square(21, 0.2, 0.49, 1).unwrap();
    let s = efg::solve(&case.problem, &AdrParams::default(), |_, _| {}).unwrap();
    let (e, f) = (s.energy, case.force(&s));
    eprintln!("21 x 21: W = {e:.4} J, F = {f:.3} N, {} steps", s.steps);
    let (e_ref, f_ref) = TABLE_3_2;
    assert!((e - e_ref).abs() < 0.01 * e_ref, "energy {e}");
    assert!((f - f_ref).abs() < 0.01 * f_ref, "force {f}");
    // the interpolated displacement of the pulled edge is the prescribed one (Eq. 3.18)
    let n = 21;
    for j in 0..n {
        let i = j * n + n - 1;
        assert!((s.displacement[2 * i] - 0.02).abs() < 1e-9 && s.displacement[2 * i + 1].abs() < 1e-9);
    }
}

#[test]
fn two_by_two_integration_converges_in_fewer_steps_to_the_same_answer() {
    let one = reference::square(21, 0.2, 0.49, 1).unwrap();
    let four = reference::square(21, 0.2, 0.49, 2).unwrap();
    let s1 = efg::solve(&one.problem, &AdrParams::default(), |_, _| {}).unwrap();
    let s4 = efg::solve(&four.problem, &AdrParams::default(), |_, _| {}).unwrap();
    let (e_ref, f_ref) = TABLE_3_2;
    eprintln!("1 point: {} steps, 4 points: {} steps", s1.steps, s4.steps);
    assert!((s4.energy - e_ref).abs() < 0.01 * e_ref && (four.force(&s4) - f_ref).abs() < 0.01 * f_ref);
    // the near-zero-energy modes of one-point integration are what slows the relaxation
    assert!(s4.steps * 3 < s1.steps, "{} vs {}", s4.steps, s1.steps);
}

#[test]
fn the_3d_cube_matches_table_5_2() {
    // 15³ nodes, 2 × 2 × 2 points per cell (11³: +1.4 % in energy; 13³: +0.96 %)
    let case = reference::cube(15, 0.2, 0.49, 2).unwrap();
    let s = efg::solve(&case.problem, &AdrParams::default(), |_, _| {}).unwrap();
    let (e, f) = (s.energy, case.force(&s));
    eprintln!("15^3 nodes: W = {e:.5} J, F = {f:.4} N, {} steps", s.steps);
    let (e_ref, f_ref) = reference::TABLE_5_2;
    assert!((e - e_ref).abs() < 0.01 * e_ref, "energy {e}");
    assert!((f - f_ref).abs() < 0.01 * f_ref, "force {f}");
}
