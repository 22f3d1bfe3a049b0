//! Several tools in contact with one organ at once: the forces that displace k surface points
//! by their penetrations together.
//!
//! With `C(i ← j)` the compliance between contact points ([`Vademecum::cross_compliance`]:
//! the displacement at i per unit force at j), the tools' forces on the tissue solve
//!
//! `Σ_j C(i ← j) f_j = δ_i`,  i = 1 … k
//!
//! — one 3k × 3k system, so that pressing with one tool moves the tissue under the others and
//! changes their forces (superposition of the linear responses; for k = 1 it is the single
//! tool's `f = C⁻¹δ`, [`Vademecum::contact_force`]). The system is symmetric by reciprocity
//! (`C(j ← i) = C(i ← j)ᵀ`) and positive definite for distinct points of a supported organ;
//! two tools on the same spot make it singular, and it is refused then, as an ill-conditioned
//! single compliance is. Everything lives on the stack: a tick may call it.

use super::vademecum::Vademecum;

/// Most contacts solved together (tools in one session).
pub const MAX_CONTACTS: usize = 4;

/// Largest system: three equations per contact.
const N: usize = 3 * MAX_CONTACTS;

/// Smallest accepted pivot, relative to the largest diagonal entry of the system: below it the
/// contacts are taken as not independent (two tools on one spot) and nothing is solved.
const MIN_RELATIVE_PIVOT: f64 = 1e-10;

/// Why the contacts could not be solved together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CoupledError {
    /// More contacts than [`MAX_CONTACTS`].
    #[error("{0} contacts; at most {MAX_CONTACTS} are solved together")]
    TooMany(usize),
    /// A contact point the vademecum cannot load, or a non-finite input.
    #[error("contact {0} is not on the loadable surface or not finite")]
    NotLoadable(usize),
    /// The contacts are not independent (two tools on one spot): the system is singular.
    #[error("the contacts are not independent (two tools on one spot)")]
    Singular,
}

/// The forces (N) on the tissue at `points` (each `(nodes, barycentric weights)` on the
/// loadable surface) that displace them by `penetrations` (m) together, into `forces` (one per
/// point; module docs). Allocates nothing.
pub fn coupled_forces(
    v: &Vademecum,
    points: &[([usize; 3], [f64; 3])],
    penetrations: &[[f64; 3]],
    forces: &mut [[f64; 3]],
) -> Result<(), CoupledError> {
    let k = points.len();
    assert!(
        penetrations.len() == k && forces.len() == k,
        "one penetration and one force per point"
    );
    if k > MAX_CONTACTS {
        return Err(CoupledError::TooMany(k));
    }
    if k == 0 {
        return Ok(());
    }
    let n = 3 * k;
    let mut a = [[0.0; N]; N];
    let mut b = [0.0; N];
    for i in 0..k {
        if penetrations[i].iter().any(|x| !x.is_finite()) {
            return Err(CoupledError::NotLoadable(i));
        }
        for j in 0..k {
            let c = v.cross_compliance(points[i], points[j]).ok_or(CoupledError::NotLoadable(j))?;
            for (r, row) in c.iter().enumerate() {
                a[3 * i + r][3 * j..3 * j + 3].copy_from_slice(row);
            }
        }
        b[3 * i..3 * i + 3].copy_from_slice(&penetrations[i]);
    }
    let x = solve(&mut a, &mut b, n).ok_or(CoupledError::Singular)?;
    for (f, chunk) in forces.iter_mut().zip(x[..n].chunks_exact(3)) {
        *f = [chunk[0], chunk[1], chunk[2]];
    }
    Ok(())
}

/// Solves the leading `n × n` block of `a x = b` by Gaussian elimination with partial
/// pivoting; `None` when a pivot falls below [`MIN_RELATIVE_PIVOT`] of the largest diagonal
/// entry or the solution is not finite.
fn solve(a: &mut [[f64; N]; N], b: &mut [f64; N], n: usize) -> Option<[f64; N]> {
    let scale = (0..n).map(|i| a[i][i].abs()).fold(0.0, f64::max);
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    for col in 0..n {
        let pivot = (col..n).max_by(|&p, &q| a[p][col].abs().total_cmp(&a[q][col].abs()))?;
        if a[pivot][col].abs() <= MIN_RELATIVE_PIVOT * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..n {
            let m = a[row][col] / a[col][col];
            if m != 0.0 {
                for c in col..n {
                    a[row][c] -= m * a[col][c];
                }
                b[row] -= m * b[col];
            }
        }
    }
    let mut x = [0.0; N];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|c| a[row][c] * x[c]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x[..n].iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_elimination_solves_a_small_system_and_refuses_a_singular_one() {
        let mut a = [[0.0; N]; N];
        let mut b = [0.0; N];
        // [[4, 1, 0], [1, 3, 1], [0, 1, 2]] x = [1, 2, 3]: x = [2/9, 1/9, 13/9]
        a[0][..3].copy_from_slice(&[4.0, 1.0, 0.0]);
        a[1][..3].copy_from_slice(&[1.0, 3.0, 1.0]);
        a[2][..3].copy_from_slice(&[0.0, 1.0, 2.0]);
        b[..3].copy_from_slice(&[1.0, 2.0, 3.0]);
        let x = solve(&mut a, &mut b, 3).unwrap();
        for (got, want) in x[..3].iter().zip([2.0 / 9.0, 1.0 / 9.0, 13.0 / 9.0]) {
            assert!((got - want).abs() < 1e-14, "{got} {want}");
        }
        // two equal rows: singular
        let mut a = [[0.0; N]; N];
        a[0][..2].copy_from_slice(&[1.0, 2.0]);
        a[1][..2].copy_from_slice(&[1.0, 2.0]);
        assert!(solve(&mut a, &mut [1.0; N], 2).is_none());
    }
}
