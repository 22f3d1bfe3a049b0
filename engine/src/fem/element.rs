//! Cell-level operators: stiffness (with the locking-free options), mass, stress.
//!
//! Matrices are written row-major into caller-provided slices of size `(3n)²` (stiffness) or
//! `n²` (scalar mass, to be multiplied by the 3×3 identity), where `n` is the number of nodes
//! of the cell and degree of freedom `3a+i` is component `i` of node `a`.

use serde::{Deserialize, Serialize};

use crate::material::LinearElastic;
use crate::mesh::CellKind;
use crate::mesh::shape;

/// How the volumetric part of the stiffness is integrated (what fights volumetric locking as
/// ν → ½).
///
/// - `None`: full integration of everything (2×2×2 Gauss on hexahedra). Locks as ν → ½.
/// - `Sri`: selective reduced integration: the volumetric term `κ a_i b_j` at the single
///   centre point, the deviatoric term at 2×2×2.
/// - `Bbar`: the mean-dilatation B̄ method (Hughes 1980): the volumetric term uses the
///   cell-averaged gradients `ā = (1/V)∫ ∇N_a dV`, i.e. a constant pressure per cell.
///
/// On hexahedra `Sri` and `Bbar` coincide for parallelepipeds. On distorted cells they
/// differ, and only `Bbar` passes the patch test: one-point integration uses
/// `8 det J(0) ∇N(0)` where consistency needs `∫ ∇N dV` (Flanagan & Belytschko 1981), hence
/// `Bbar` is the default and `Sri` is kept for comparison. On linear tetrahedra the strain is already
/// constant per cell, so those three options give the same matrix, and tet4 locks as ν → ½.
///
/// - `Nodal`: the averaged-nodal-pressure tetrahedron (Bonet & Burton 1998, [`super::nodal`]):
///   the dilatation is averaged over the cells around each node, one volumetric constraint per
///   node instead of per cell. The cell matrix holds the deviatoric term only; the assembly
///   adds the nodal volumetric terms, which couple a node's neighbours' neighbours. On
///   hexahedra it is the same as `Bbar` (the scene refuses the combination).
///
/// Measured in `BENCHMARKS.md`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Locking {
    /// Full integration.
    None,
    /// Selective reduced integration.
    Sri,
    /// Mean-dilatation B̄.
    #[default]
    Bbar,
    /// Averaged nodal pressure (linear tetrahedra).
    Nodal,
}

/// A cell operator could not be computed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ElementError {
    /// The Jacobian determinant is not positive at an integration point: the cell is inverted
    /// or degenerate.
    #[error("cell is inverted or degenerate (Jacobian determinant {det:.3e} at an integration point)")]
    NonPositiveJacobian {
        /// The determinant found.
        det: f64,
    },
}

/// Working memory for one cell (no allocation per cell).
#[derive(Debug, Clone)]
pub struct ElementScratch {
    grad: [[f64; 3]; 8],
    gbar: [[f64; 3]; 8],
    hex_dn: [[[f64; 3]; 8]; 8],
    hex_n: [[f64; 8]; 8],
    hex_dn_centre: [[f64; 3]; 8],
}

impl Default for ElementScratch {
    fn default() -> Self {
        let g = shape::hex_gauss_2();
        let mut hex_dn = [[[0.0; 3]; 8]; 8];
        let mut hex_n = [[0.0; 8]; 8];
        for q in 0..8 {
            hex_dn[q] = shape::hex_dn(g[q]);
            hex_n[q] = shape::hex_n(g[q]);
        }
        Self {
            grad: [[0.0; 3]; 8],
            gbar: [[0.0; 3]; 8],
            hex_dn,
            hex_n,
            hex_dn_centre: shape::hex_dn([0.0; 3]),
        }
    }
}

/// Adds `w · [κ a_i b_j]` (volumetric, if `vol`) and `w · μ(a_j b_i + δ_ij a·b − ⅔ a_i b_j)`
/// (deviatoric, if `dev`) for all node pairs into `ke`.
#[inline]
pub(crate) fn add_terms(ke: &mut [f64], n: usize, g: &[[f64; 3]], w: f64, kappa: f64, mu: f64, vol: bool, dev: bool) {
    let nd = 3 * n;
    for a in 0..n {
        let ga = g[a];
        for b in 0..n {
            let gb = g[b];
            let dot = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
            for i in 0..3 {
                let row = (3 * a + i) * nd + 3 * b;
                for j in 0..3 {
                    let mut v = 0.0;
                    if vol {
                        v += kappa * ga[i] * gb[j];
                    }
                    if dev {
                        v += mu * (ga[j] * gb[i] - 2.0 / 3.0 * ga[i] * gb[j]);
                        if i == j {
                            v += mu * dot;
                        }
                    }
                    ke[row + j] += w * v;
                }
            }
        }
    }
}

/// Cell stiffness `K^e` (see the module docs of [`crate::fem`]) into `ke` (row-major,
/// `(3n)²`, overwritten). Returns the cell volume.
pub fn stiffness(
    kind: CellKind,
    x: &[[f64; 3]],
    mat: &LinearElastic,
    locking: Locking,
    s: &mut ElementScratch,
    ke: &mut [f64],
) -> Result<f64, ElementError> {
    let n = kind.nodes_per_cell();
    debug_assert_eq!(ke.len(), 9 * n * n);
    debug_assert_eq!(x.len(), n);
    ke.fill(0.0);
    let (kappa, mu) = (mat.bulk(), mat.shear());
    match kind {
        CellKind::Tet4 => {
            let det = shape::physical_gradients(x, &shape::TET_DN, &mut s.grad[..4]);
            if det <= 0.0 {
                return Err(ElementError::NonPositiveJacobian { det });
            }
            let vol = det / 6.0;
            // with the nodal pressure, the volumetric term is assembled over nodal patches
            add_terms(ke, 4, &s.grad[..4], vol, kappa, mu, locking != Locking::Nodal, true);
            Ok(vol)
        }
        CellKind::Hex8 => {
            let mut vol = 0.0;
            for g in s.gbar.iter_mut() {
                *g = [0.0; 3];
            }
            for q in 0..8 {
                let det = shape::physical_gradients(x, &s.hex_dn[q], &mut s.grad);
                if det <= 0.0 {
                    return Err(ElementError::NonPositiveJacobian { det });
                }
                vol += det;
                add_terms(ke, 8, &s.grad, det, kappa, mu, locking == Locking::None, true);
                if matches!(locking, Locking::Bbar | Locking::Nodal) {
                    for a in 0..8 {
                        for i in 0..3 {
                            s.gbar[a][i] += det * s.grad[a][i];
                        }
                    }
                }
            }
            match locking {
                Locking::None => {}
                Locking::Sri => {
                    let det = shape::physical_gradients(x, &s.hex_dn_centre, &mut s.grad);
                    if det <= 0.0 {
                        return Err(ElementError::NonPositiveJacobian { det });
                    }
                    add_terms(ke, 8, &s.grad, 8.0 * det, kappa, mu, true, false);
                }
                Locking::Bbar | Locking::Nodal => {
                    for g in s.gbar.iter_mut() {
                        for c in g.iter_mut() {
                            *c /= vol;
                        }
                    }
                    let gbar = s.gbar;
                    add_terms(ke, 8, &gbar, vol, kappa, mu, true, false);
                }
            }
            Ok(vol)
        }
    }
}

/// Stress at the cell centre in Voigt order `[σxx, σyy, σzz, σxy, σyz, σzx]` (Pa), from the
/// cell's nodal displacements `u` (flat, `3n`). The volumetric part follows the same locking
/// option as the stiffness: `σ = κ θ I + 2μ dev ε`, with θ the (averaged) dilatation; with
/// [`Locking::Nodal`] on tetrahedra the pressure `κ θ` is `pressure`, the average of the
/// cell's nodal pressures (which the caller assembles), and is otherwise ignored.
pub fn stress(
    kind: CellKind,
    x: &[[f64; 3]],
    u: &[f64],
    mat: &LinearElastic,
    locking: Locking,
    pressure: Option<f64>,
    s: &mut ElementScratch,
) -> Result<[f64; 6], ElementError> {
    let n = kind.nodes_per_cell();
    let mut dn = [[0.0; 3]; 8];
    match kind {
        CellKind::Tet4 => dn[..4].copy_from_slice(&shape::TET_DN),
        CellKind::Hex8 => dn = s.hex_dn_centre,
    }
    let det = shape::physical_gradients(x, &dn[..n], &mut s.grad[..n]);
    if det <= 0.0 {
        return Err(ElementError::NonPositiveJacobian { det });
    }
    let mut e = [[0.0; 3]; 3];
    for a in 0..n {
        for i in 0..3 {
            for j in 0..3 {
                e[i][j] += 0.5 * (u[3 * a + i] * s.grad[a][j] + u[3 * a + j] * s.grad[a][i]);
            }
        }
    }
    let mut theta = e[0][0] + e[1][1] + e[2][2];
    if kind == CellKind::Hex8 && matches!(locking, Locking::Bbar | Locking::Nodal) {
        // mean dilatation: θ̄ = (1/V) Σ_q det_q Σ_a ∇N_a(q)·u_a
        let (mut num, mut vol) = (0.0, 0.0);
        for q in 0..8 {
            let det = shape::physical_gradients(x, &s.hex_dn[q], &mut s.grad);
            vol += det;
            for a in 0..8 {
                num += det * (0..3).map(|i| s.grad[a][i] * u[3 * a + i]).sum::<f64>();
            }
        }
        theta = num / vol;
    }
    let (kappa, mu) = (mat.bulk(), mat.shear());
    let tr = e[0][0] + e[1][1] + e[2][2];
    let p = match (kind, locking, pressure) {
        (CellKind::Tet4, Locking::Nodal, Some(p)) => p,
        _ => kappa * theta,
    };
    Ok([
        p + 2.0 * mu * (e[0][0] - tr / 3.0),
        p + 2.0 * mu * (e[1][1] - tr / 3.0),
        p + 2.0 * mu * (e[2][2] - tr / 3.0),
        2.0 * mu * e[0][1],
        2.0 * mu * e[1][2],
        2.0 * mu * e[2][0],
    ])
}

/// Von Mises equivalent stress `√(3/2 s:s)` of a Voigt stress (Pa).
pub fn von_mises(s: [f64; 6]) -> f64 {
    let [xx, yy, zz, xy, yz, zx] = s;
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2)) + 3.0 * (xy * xy + yz * yz + zx * zx)).sqrt()
}

/// Scalar consistent mass `M_ab = ρ ∫ N_a N_b dV` into `me` (row-major `n²`, overwritten;
/// the vector mass is `M_ab I₃`). Tetrahedron: `ρV/20 (1 + δ_ab)`; hexahedron: 2×2×2 Gauss.
pub fn consistent_mass(kind: CellKind, x: &[[f64; 3]], rho: f64, s: &ElementScratch, me: &mut [f64]) -> Result<(), ElementError> {
    let n = kind.nodes_per_cell();
    debug_assert_eq!(me.len(), n * n);
    me.fill(0.0);
    match kind {
        CellKind::Tet4 => {
            let det = shape::jacobian_det(x, &shape::TET_DN);
            if det <= 0.0 {
                return Err(ElementError::NonPositiveJacobian { det });
            }
            let v = det / 6.0;
            for a in 0..4 {
                for b in 0..4 {
                    me[a * 4 + b] = rho * v / 20.0 * if a == b { 2.0 } else { 1.0 };
                }
            }
        }
        CellKind::Hex8 => {
            for q in 0..8 {
                let det = shape::jacobian_det(x, &s.hex_dn[q]);
                if det <= 0.0 {
                    return Err(ElementError::NonPositiveJacobian { det });
                }
                let nq = &s.hex_n[q];
                for a in 0..8 {
                    for b in 0..8 {
                        me[a * 8 + b] += rho * det * nq[a] * nq[b];
                    }
                }
            }
        }
    }
    Ok(())
}

/// Lumped (row-sum) mass `m_a = ρ ∫ N_a dV` into `m` (length n). Also the weights that turn a
/// body force density into nodal forces.
pub fn lumped_mass(kind: CellKind, x: &[[f64; 3]], rho: f64, s: &ElementScratch, m: &mut [f64]) -> Result<(), ElementError> {
    let n = kind.nodes_per_cell();
    let mut me = [0.0; 64];
    consistent_mass(kind, x, rho, s, &mut me[..n * n])?;
    for a in 0..n {
        m[a] = me[a * n..(a + 1) * n].iter().sum();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shape::HEX_NODES;

    fn distorted_hex() -> Vec<[f64; 3]> {
        HEX_NODES
            .iter()
            .enumerate()
            .map(|(a, p)| {
                let d = 0.07 * ((a * 7 % 5) as f64 - 2.0);
                [
                    0.5 * p[0] + 0.6 + d,
                    0.4 * p[1] + 0.1 * p[0] - d * 0.5,
                    0.3 * p[2] + 0.05 * p[1] + 0.3 * d,
                ]
            })
            .collect()
    }

    fn tet() -> Vec<[f64; 3]> {
        vec![[0.1, 0.0, 0.0], [1.0, 0.2, 0.1], [0.3, 0.9, 0.0], [0.2, 0.3, 1.1]]
    }

    fn check_symmetric_and_rigid(kind: CellKind, x: &[[f64; 3]], locking: Locking) {
        let n = kind.nodes_per_cell();
        let mat = LinearElastic::new(1000.0, 0.3).unwrap();
        let mut s = ElementScratch::default();
        let mut ke = vec![0.0; 9 * n * n];
        stiffness(kind, x, &mat, locking, &mut s, &mut ke).unwrap();
        let scale = ke.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let nd = 3 * n;
        for r in 0..nd {
            for c in 0..nd {
                assert!(
                    (ke[r * nd + c] - ke[c * nd + r]).abs() <= 1e-12 * scale,
                    "K not symmetric at ({r},{c})"
                );
            }
        }
        // Six rigid modes: 3 translations, 3 rotations u = ω × x.
        let modes: Vec<Box<dyn Fn([f64; 3]) -> [f64; 3]>> = vec![
            Box::new(|_| [1.0, 0.0, 0.0]),
            Box::new(|_| [0.0, 1.0, 0.0]),
            Box::new(|_| [0.0, 0.0, 1.0]),
            Box::new(|p| [0.0, -p[2], p[1]]),
            Box::new(|p| [p[2], 0.0, -p[0]]),
            Box::new(|p| [-p[1], p[0], 0.0]),
        ];
        for m in modes {
            let u: Vec<f64> = x.iter().flat_map(|p| m(*p)).collect();
            for r in 0..nd {
                let f: f64 = (0..nd).map(|c| ke[r * nd + c] * u[c]).sum();
                assert!(f.abs() <= 1e-12 * scale, "rigid mode gives force {f} (scale {scale})");
            }
        }
    }

    #[test]
    fn stiffness_is_symmetric_and_annihilates_rigid_modes() {
        for l in [Locking::None, Locking::Sri, Locking::Bbar] {
            check_symmetric_and_rigid(CellKind::Hex8, &distorted_hex(), l);
            check_symmetric_and_rigid(CellKind::Tet4, &tet(), l);
        }
    }

    #[test]
    fn mass_sums_to_cell_mass() {
        let s = ElementScratch::default();
        let mut me = vec![0.0; 64];
        consistent_mass(CellKind::Hex8, &distorted_hex(), 1000.0, &s, &mut me).unwrap();
        let total: f64 = me.iter().sum();
        let mut x = distorted_hex();
        let mut ke = vec![0.0; 576];
        let mut s2 = ElementScratch::default();
        let vol = stiffness(
            CellKind::Hex8,
            &x,
            &LinearElastic::new(1.0, 0.2).unwrap(),
            Locking::None,
            &mut s2,
            &mut ke,
        )
        .unwrap();
        assert!((total - 1000.0 * vol).abs() < 1e-9 * total);
        x.truncate(4);
        let mut m = [0.0; 4];
        lumped_mass(CellKind::Tet4, &tet(), 2.0, &s, &mut m).unwrap();
        let v = shape::jacobian_det(&tet(), &shape::TET_DN) / 6.0;
        for mi in m {
            assert!((mi - 2.0 * v / 4.0).abs() < 1e-14);
        }
    }

    #[test]
    fn inverted_cell_is_an_error() {
        let mut x = tet();
        x.swap(1, 2);
        let mut ke = vec![0.0; 144];
        let r = stiffness(
            CellKind::Tet4,
            &x,
            &LinearElastic::new(1.0, 0.3).unwrap(),
            Locking::None,
            &mut ElementScratch::default(),
            &mut ke,
        );
        assert!(matches!(r, Err(ElementError::NonPositiveJacobian { .. })));
    }

    #[test]
    fn von_mises_of_uniaxial_stress_is_the_stress() {
        assert!((von_mises([5.0, 0.0, 0.0, 0.0, 0.0, 0.0]) - 5.0).abs() < 1e-14);
        assert!((von_mises([0.0, 0.0, 0.0, 2.0, 0.0, 0.0]) - 2.0 * 3f64.sqrt()).abs() < 1e-14);
    }
}
