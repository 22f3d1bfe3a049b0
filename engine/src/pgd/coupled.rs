//! Several tools in contact with one organ at once: the forces that press k surface points
//! by their penetrations together.
//!
//! Each tool alone pushes the tissue with its contact law, `f_i = K_i δ_i`
//! ([`Vademecum::contact_stiffness`] for the tool's [`Footprint`]; `δ_i = −depth_i n_i`
//! along the surface's normal). Together, each keeps that law's **direction**, `f_i = a_i
//! f̂_i` with `f̂_i = K_i n_i`, and the scalars `a_i` solve
//!
//! `Σ_j S_ij a_j = r_i`,  `S_ij = γ_i γ_j f̂_iᵀ C(i ← j) f̂_j`,  `r_i = f̂_iᵀ δ_i`,  i = 1 … k,
//!
//! with `C(i ← j)` the compliance between the contact points
//! ([`Vademecum::cross_compliance`]: the displacement at i per unit force at j) and `γ_i` the
//! scale that makes each own entry the tool-alone law's, `S_ii = n_iᵀ K_i n_i` (1 where `K_i⁻¹`
//! is the point's own block `C(i ← i)`, as at the load nodes). This is the Galerkin projection
//! of the tissue's response on the tools' force directions: row i says that the tissue under
//! tool i, displaced by every tool's force, has moved by tool i's penetration as tool i
//! measures displacement (along `f̂_i`); pressing with one tool moves the tissue under the
//! others and changes their forces (superposition of the linear responses). For k = 1 it is
//! the tool-alone law `f = K δ`. `S` is a Gram matrix of the organ's compliance (symmetric by
//! reciprocity, `C(j ← i) = C(i ← j)ᵀ`; positive definite for distinct points of a supported
//! organ), so the problem of probes that only push (`a_i ≤ 0`) is a convex one with one
//! solution that moves continuously with the tools: a probe touching the tissue another one
//! moves takes its load from zero (a system that imposed the whole displacement vector at each
//! contact pinned the tissue's sideways motion there the moment it touched: a step of the other
//! tool's force). Two tools on one spot make it singular, and it is refused then, as an
//! ill-conditioned single compliance is. Everything lives on the stack: a tick may call it.

use super::vademecum::{Footprint, Vademecum};

/// Most contacts solved together (tools in one session).
pub const MAX_CONTACTS: usize = 4;

/// Largest system: one equation per contact.
const N: usize = MAX_CONTACTS;

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
/// loadable surface, with its outward unit normal in `normals` and its tool's footprint in
/// `footprints`) that press them by `penetrations` (m) together, into `forces` (one per point;
/// module docs). Allocates nothing.
pub fn coupled_forces(
    v: &Vademecum,
    points: &[([usize; 3], [f64; 3])],
    footprints: &[Footprint],
    normals: &[[f64; 3]],
    penetrations: &[[f64; 3]],
    forces: &mut [[f64; 3]],
) -> Result<(), CoupledError> {
    let k = points.len();
    assert!(
        footprints.len() == k && normals.len() == k && penetrations.len() == k && forces.len() == k,
        "one footprint, one normal, one penetration and one force per point"
    );
    if k > MAX_CONTACTS {
        return Err(CoupledError::TooMany(k));
    }
    if k == 0 {
        return Ok(());
    }
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let apply = |m: &[[f64; 3]; 3], x: &[f64; 3]| m.map(|row| dot(&row, x));
    // each tool's force direction f̂_i = K_i n_i and its scale γ_i
    let mut dirs = [[0.0; 3]; MAX_CONTACTS];
    let mut gamma = [0.0; MAX_CONTACTS];
    let mut a = [[0.0; N]; N];
    let mut b = [0.0; N];
    for i in 0..k {
        let (n, delta) = (&normals[i], &penetrations[i]);
        if n.iter().chain(delta).any(|x| !x.is_finite()) {
            return Err(CoupledError::NotLoadable(i));
        }
        let stiffness = v
            .contact_stiffness(points[i].0, points[i].1, footprints[i])
            .ok_or(CoupledError::NotLoadable(i))?;
        let own = v.cross_compliance(points[i], points[i]).ok_or(CoupledError::NotLoadable(i))?;
        let f = apply(&stiffness, n);
        let (alone, blend) = (dot(n, &f), dot(&f, &apply(&own, &f)));
        if !(alone > 0.0 && blend > 0.0) {
            return Err(CoupledError::Singular);
        }
        dirs[i] = f;
        gamma[i] = (alone / blend).sqrt();
        b[i] = dot(&f, delta);
    }
    for i in 0..k {
        for j in 0..k {
            let c = v.cross_compliance(points[i], points[j]).ok_or(CoupledError::NotLoadable(j))?;
            a[i][j] = gamma[i] * gamma[j] * dot(&dirs[i], &apply(&c, &dirs[j]));
        }
    }
    let x = solve(&mut a, &mut b, k).ok_or(CoupledError::Singular)?;
    for ((f, d), s) in forces.iter_mut().zip(&dirs).zip(&x[..k]) {
        *f = d.map(|c| s * c);
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
