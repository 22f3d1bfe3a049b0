//! The meshless solver (seed 004) against its published references.

use vademecum_engine::meshless::efg::{self, AdrParams};
use vademecum_engine::meshless::reference::{self, TABLE_3_2};

#[test]
fn the_2d_square_matches_table_3_2() {
    let case = reference::square(21, 0.2, 0.49).unwrap();
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
