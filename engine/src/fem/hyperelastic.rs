//! Total Lagrangian cells for large deformations: strain energy, internal forces and the
//! consistent tangent of a hyperelastic cell, on the reference configuration.
//!
//! # The method
//! With `F = I + ∇₀u`, `C = FᵀF`, `S = 2∂W/∂C` ([`Hyperelastic`]), the cell's energy is
//! `Π_e = ∫ W(C) dV₀`; its gradient (internal forces) and Hessian (tangent) are, with
//! `G_a = ∂N_a/∂X` and `P = F S`,
//!
//! `f_{ai} = ∫ P_{iJ} G_{aJ} dV₀`,
//!
//! `K_{ai,bk} = ∫ [ δ_{ik} G_a·S G_b  +  (B_a)ᵀ ℂ (B_b) ] dV₀`,
//!
//! where `B_a` maps a nodal velocity to the Voigt rate of the Green strain (engineering shear):
//! `(B_a)_{(I,J), i} = F_{iI} G_{aJ} + F_{iJ} G_{aI}` (one term when `I = J`). The first term is
//! the geometric stiffness, the second the material stiffness (Bonet & Wood, ch. 7).
//!
//! # Locking
//! Trilinear hexahedra integrated fully lock as ν → ½ (the seed 004 cube loses about 3 %).
//! [`Volumetric::MeanDilatation`] is the finite-strain B̄ (the Q1/P0 element of Simo, Taylor
//! & Pister 1985), written as an energy so its tangent is exact and symmetric: the volumetric
//! energy `U` of a law that splits is evaluated once per cell on the cell's volume ratio
//! `θ = v/V` (`v = ∫ J dV₀`), `Π_e = ∫ W̄(C) dV₀ + V U(θ)`, giving
//!
//! `f_{ai} += U'(θ) g_{ai}`, `g_{ai} = ∫ J h_{ai} dV₀` with `h_a = F⁻ᵀ G_a` (`= ∫ ∂N_a/∂x dv`),
//!
//! `K_{ai,bk} += U''(θ)/V g_{ai} g_{bk} + U'(θ) ∫ J (h_{ai} h_{bk} − h_{ak} h_{bi}) dV₀`.
//!
//! St Venant–Kirchhoff does not split and is always integrated point by point.

use nalgebra::Matrix3;

use crate::material::hyperelastic::{Hyperelastic, Part, VOIGT};
use crate::mesh::CellKind;
use crate::mesh::shape;

/// How the volumetric energy is integrated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Volumetric {
    /// At every integration point, with the point's `J` (locks as ν → ½ on hexahedra).
    PointWise,
    /// Once per cell, on the cell's volume ratio (see the [module docs](self)).
    #[default]
    MeanDilatation,
    /// Once per node, on the nodal volume ratio: the averaged-nodal-pressure tetrahedron
    /// ([`super::nodal`]). [`cell`] then evaluates the isochoric part only and the assembly
    /// adds the nodal volumetric terms; on hexahedra it is [`Volumetric::MeanDilatation`].
    Nodal,
}

impl Volumetric {
    /// The large-deformation counterpart of a scene's locking treatment: full integration for
    /// `none`, the mean dilatation for `sri` and `bbar`, the nodal pressure for `nodal`.
    pub fn for_locking(locking: super::Locking) -> Self {
        match locking {
            super::Locking::None => Self::PointWise,
            super::Locking::Sri | super::Locking::Bbar => Self::MeanDilatation,
            super::Locking::Nodal => Self::Nodal,
        }
    }

    /// Whether cells of `kind` with `law` evaluate `U` once per cell on the cell's volume ratio.
    fn per_cell(self, kind: CellKind, law: &Hyperelastic) -> bool {
        law.splits()
            && match self {
                Self::PointWise => false,
                Self::MeanDilatation => true,
                Self::Nodal => kind == CellKind::Hex8,
            }
    }

    /// Whether cells of `kind` with `law` leave `U` to the nodal assembly.
    pub fn per_node(self, kind: CellKind, law: &Hyperelastic) -> bool {
        law.splits() && self == Self::Nodal && kind == CellKind::Tet4
    }
}

/// The hyperelastic law of every cell (later scene entries override earlier ones).
#[derive(Debug, Clone, PartialEq)]
pub struct LawMap {
    /// The distinct laws.
    pub laws: Vec<Hyperelastic>,
    /// Index into `laws` for each cell.
    pub of_cell: Vec<u16>,
}

impl LawMap {
    /// One law for `n_cells` cells.
    pub fn uniform(law: Hyperelastic, n_cells: usize) -> Self {
        Self {
            laws: vec![law],
            of_cell: vec![0; n_cells],
        }
    }

    /// The law of cell `c`.
    pub fn of(&self, c: usize) -> &Hyperelastic {
        &self.laws[self.of_cell[c] as usize]
    }
}

/// A cell's deformation is not admissible.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CellError {
    /// The reference cell is inverted or degenerate.
    #[error("the reference cell is inverted or degenerate (Jacobian determinant {det:.3e})")]
    Reference {
        /// The determinant found.
        det: f64,
    },
    /// The deformation inverts the cell at an integration point (`det F ≤ 0`).
    #[error("the deformation inverts the cell (det F = {det_f:.3e} at an integration point)")]
    Inverted {
        /// `det F` found.
        det_f: f64,
    },
    /// The cell's volume ratio is not positive (mean dilatation).
    #[error("the cell's volume ratio is not positive ({theta:.3e})")]
    Volume {
        /// `θ = v/V`.
        theta: f64,
    },
}

/// What one cell evaluation returns, besides the forces and tangent written in place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellState {
    /// Strain energy (J).
    pub energy: f64,
    /// Reference volume (m³).
    pub volume: f64,
}

/// Working memory for one cell.
#[derive(Debug, Clone)]
pub struct CellScratch {
    points: Vec<([f64; 3], [[f64; 3]; 8])>,
    g: [[f64; 3]; 8],
    h: [[[f64; 3]; 8]; 8],
    jw: [f64; 8],
}

impl CellScratch {
    /// For cells of `kind`: the integration points and reference shape-function derivatives.
    pub fn new(kind: CellKind) -> Self {
        let points = match kind {
            CellKind::Tet4 => {
                let mut dn = [[0.0; 3]; 8];
                dn[..4].copy_from_slice(&shape::TET_DN);
                vec![([0.25; 3], dn)]
            }
            CellKind::Hex8 => shape::hex_gauss_2().iter().map(|&p| (p, shape::hex_dn(p))).collect(),
        };
        Self {
            points,
            g: [[0.0; 3]; 8],
            h: [[[0.0; 3]; 8]; 8],
            jw: [0.0; 8],
        }
    }
}

/// Visits the integration points of the reference cell `x`: `visit(dV₀, G)` with the point's
/// weighted reference volume and the physical gradients `G_a = ∂N_a/∂X` of its `n` shape
/// functions (the same rule [`cell`] integrates with).
pub fn for_each_point(
    kind: CellKind,
    x: &[[f64; 3]],
    s: &mut CellScratch,
    mut visit: impl FnMut(f64, &[[f64; 3]]),
) -> Result<(), CellError> {
    let n = kind.nodes_per_cell();
    let tet_weight = if kind == CellKind::Tet4 { 1.0 / 6.0 } else { 1.0 };
    for q in 0..s.points.len() {
        let det = shape::physical_gradients(x, &s.points[q].1[..n], &mut s.g[..n]);
        if det <= 0.0 {
            return Err(CellError::Reference { det });
        }
        visit(det * tet_weight, &s.g[..n]);
    }
    Ok(())
}

/// Energy, internal forces `fe` (length `3n`, overwritten) and, when `ke` is given, the tangent
/// (`(3n)²`, row-major, overwritten) of one cell with reference coordinates `x` and nodal
/// displacements `u` (flat, `3n`).
pub fn cell(
    kind: CellKind,
    x: &[[f64; 3]],
    u: &[f64],
    law: &Hyperelastic,
    volumetric: Volumetric,
    s: &mut CellScratch,
    fe: &mut [f64],
    mut ke: Option<&mut [f64]>,
) -> Result<CellState, CellError> {
    let n = kind.nodes_per_cell();
    let nd = 3 * n;
    debug_assert_eq!(fe.len(), nd);
    debug_assert_eq!(u.len(), nd);
    fe.fill(0.0);
    if let Some(k) = ke.as_deref_mut() {
        debug_assert_eq!(k.len(), nd * nd);
        k.fill(0.0);
    }
    let mean = volumetric.per_cell(kind, law);
    let part = if mean || volumetric.per_node(kind, law) {
        Part::Isochoric
    } else {
        Part::Full
    };
    let tet_weight = if kind == CellKind::Tet4 { 1.0 / 6.0 } else { 1.0 };
    let (mut energy, mut volume, mut v_current) = (0.0, 0.0, 0.0);
    let mut gsum = [[0.0; 3]; 8];
    for q in 0..s.points.len() {
        let det = shape::physical_gradients(x, &s.points[q].1[..n], &mut s.g[..n]);
        if det <= 0.0 {
            return Err(CellError::Reference { det });
        }
        let dv = det * tet_weight;
        volume += dv;
        let f = deformation_gradient(u, &s.g[..n]);
        let det_f: f64 = f.determinant();
        if det_f.is_nan() || det_f <= 0.0 {
            return Err(CellError::Inverted { det_f });
        }
        let c = f.transpose() * f;
        let r = law.response(&c, part).ok_or(CellError::Inverted { det_f })?;
        energy += r.energy * dv;
        let sm = Matrix3::from_fn(|i, j| {
            let p = VOIGT
                .iter()
                .position(|&(a, b)| (a, b) == (i.min(j), i.max(j)) || (b, a) == (i.min(j), i.max(j)));
            r.stress[p.expect("every pair has a Voigt index")]
        });
        let p = f * sm;
        for a in 0..n {
            for i in 0..3 {
                fe[3 * a + i] += dv * (0..3).map(|jj| p[(i, jj)] * s.g[a][jj]).sum::<f64>();
            }
        }
        if mean {
            // h_a = F⁻ᵀ G_a; g_a += J h_a dV₀
            let fit = f.try_inverse().ok_or(CellError::Inverted { det_f })?.transpose();
            for a in 0..n {
                let ga = nalgebra::Vector3::from(s.g[a]);
                let h = fit * ga;
                s.h[q][a] = [h[0], h[1], h[2]];
                for i in 0..3 {
                    gsum[a][i] += det_f * dv * h[i];
                }
            }
            s.jw[q] = det_f * dv;
            v_current += det_f * dv;
        }
        let Some(k) = ke.as_deref_mut() else { continue };
        // B_a (6×3): the Voigt Green-strain rate of node a's velocity
        let mut bmat = [[[0.0; 3]; 6]; 8];
        for a in 0..n {
            for (pv, &(ii, jj)) in VOIGT.iter().enumerate() {
                for i in 0..3 {
                    bmat[a][pv][i] = if ii == jj {
                        f[(i, ii)] * s.g[a][ii]
                    } else {
                        f[(i, ii)] * s.g[a][jj] + f[(i, jj)] * s.g[a][ii]
                    };
                }
            }
        }
        for a in 0..n {
            // ℂ B_a, once per a
            let mut cb = [[0.0; 3]; 6];
            for pv in 0..6 {
                for i in 0..3 {
                    cb[pv][i] = (0..6).map(|qv| r.tangent[pv][qv] * bmat[a][qv][i]).sum();
                }
            }
            for b in 0..n {
                // geometric: G_a · S G_b on the diagonal of the 3×3 block
                let geo: f64 = (0..3)
                    .map(|ii| (0..3).map(|jj| s.g[a][ii] * sm[(ii, jj)] * s.g[b][jj]).sum::<f64>())
                    .sum();
                for i in 0..3 {
                    for kk in 0..3 {
                        // material: (B_b)ᵀ ℂ B_a, symmetric in (a,i) ↔ (b,k)
                        let mat: f64 = (0..6).map(|pv| bmat[b][pv][kk] * cb[pv][i]).sum();
                        k[(3 * a + i) * nd + 3 * b + kk] += dv * (mat + if i == kk { geo } else { 0.0 });
                    }
                }
            }
        }
    }
    if mean {
        let theta = v_current / volume;
        if theta.is_nan() || theta <= 0.0 {
            return Err(CellError::Volume { theta });
        }
        let (uu, du, ddu) = law.volumetric(theta);
        energy += volume * uu;
        for a in 0..n {
            for i in 0..3 {
                fe[3 * a + i] += du * gsum[a][i];
            }
        }
        if let Some(k) = ke {
            for a in 0..n {
                for b in 0..n {
                    for i in 0..3 {
                        for kk in 0..3 {
                            let mut v = ddu / volume * gsum[a][i] * gsum[b][kk];
                            for q in 0..s.points.len() {
                                let (ha, hb) = (s.h[q][a], s.h[q][b]);
                                v += du * s.jw[q] * (ha[i] * hb[kk] - ha[kk] * hb[i]);
                            }
                            k[(3 * a + i) * nd + 3 * b + kk] += v;
                        }
                    }
                }
            }
        }
    }
    Ok(CellState { energy, volume })
}

/// Cauchy stress at the cell centre in Voigt order `[σxx, σyy, σzz, σyz, σxz, σxy]` (Pa):
/// `σ = J⁻¹ F S Fᵀ`, with the volumetric part on the cell's volume ratio under
/// [`Volumetric::MeanDilatation`] (`σ_vol = U'(θ) I`), and the cell's mean nodal pressure
/// `pressure` (`p̄_e`, from the assembly) under [`Volumetric::Nodal`] on tetrahedra.
pub fn cauchy_at_centre(
    kind: CellKind,
    x: &[[f64; 3]],
    u: &[f64],
    law: &Hyperelastic,
    volumetric: Volumetric,
    pressure: Option<f64>,
    s: &mut CellScratch,
) -> Result<[f64; 6], CellError> {
    let n = kind.nodes_per_cell();
    let mean = volumetric.per_cell(kind, law);
    let nodal = volumetric.per_node(kind, law);
    let centre = match kind {
        CellKind::Tet4 => s.points[0].1,
        CellKind::Hex8 => shape::hex_dn([0.0; 3]),
    };
    let det = shape::physical_gradients(x, &centre[..n], &mut s.g[..n]);
    if det <= 0.0 {
        return Err(CellError::Reference { det });
    }
    let f = deformation_gradient(u, &s.g[..n]);
    let det_f: f64 = f.determinant();
    if det_f.is_nan() || det_f <= 0.0 {
        return Err(CellError::Inverted { det_f });
    }
    let part = if mean || nodal { Part::Isochoric } else { Part::Full };
    let r = law.response(&(f.transpose() * f), part).ok_or(CellError::Inverted { det_f })?;
    let mut sigma = f * r.stress_tensor() * f.transpose() / det_f;
    if nodal {
        sigma += pressure.unwrap_or(0.0) * Matrix3::identity();
    }
    if mean {
        // θ over the cell, from the same quadrature as the energy
        let (mut v, mut vol) = (0.0, 0.0);
        let tet_weight = if kind == CellKind::Tet4 { 1.0 / 6.0 } else { 1.0 };
        for q in 0..s.points.len() {
            let d = shape::physical_gradients(x, &s.points[q].1[..n], &mut s.g[..n]);
            vol += d * tet_weight;
            v += deformation_gradient(u, &s.g[..n]).determinant() * d * tet_weight;
        }
        let (_, du, _) = law.volumetric(v / vol);
        sigma += du * Matrix3::identity();
    }
    Ok(VOIGT.map(|(i, j)| sigma[(i, j)]))
}

/// `F = I + Σ_a u_a ⊗ G_a` from nodal displacements `u` (flat) and reference gradients `g`.
pub(crate) fn deformation_gradient(u: &[f64], g: &[[f64; 3]]) -> Matrix3<f64> {
    let mut f = Matrix3::<f64>::identity();
    for (a, ga) in g.iter().enumerate() {
        for i in 0..3 {
            for jj in 0..3 {
                f[(i, jj)] += u[3 * a + i] * ga[jj];
            }
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::LinearElastic;

    fn distorted_hex() -> Vec<[f64; 3]> {
        let mut x: Vec<[f64; 3]> = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        x[6] = [1.2, 1.1, 0.9];
        x[1][2] = 0.1;
        x.iter().map(|p| p.map(|c| 0.01 * c)).collect()
    }

    fn tet() -> Vec<[f64; 3]> {
        vec![[0.0, 0.0, 0.0], [0.01, 0.001, 0.0], [0.002, 0.012, 0.0], [0.001, 0.002, 0.009]]
    }

    fn displacement(n: usize) -> Vec<f64> {
        (0..3 * n)
            .map(|i| 1e-3 * ((i as f64 * 1.7).sin() * 0.8 + 0.1 * (i % 3) as f64))
            .collect()
    }

    fn laws() -> Vec<Hyperelastic> {
        let m = LinearElastic::new(3000.0, 0.49).unwrap();
        vec![
            Hyperelastic::svk(&m),
            Hyperelastic::neo_hookean(&m),
            Hyperelastic::mooney_rivlin(&m, 0.3).unwrap(),
        ]
    }

    /// Forces are the energy's gradient and the tangent the forces' Jacobian (central
    /// differences; the tolerance is the truncation error of a 1e-8 m step).
    #[test]
    fn forces_and_tangent_are_the_derivatives_of_the_energy() {
        for (kind, x) in [(CellKind::Hex8, distorted_hex()), (CellKind::Tet4, tet())] {
            let n = x.len();
            let u0 = displacement(n);
            for law in laws() {
                for vol in [Volumetric::PointWise, Volumetric::MeanDilatation] {
                    let mut s = CellScratch::new(kind);
                    let nd = 3 * n;
                    let (mut f, mut k) = (vec![0.0; nd], vec![0.0; nd * nd]);
                    cell(kind, &x, &u0, &law, vol, &mut s, &mut f, Some(&mut k)).unwrap();
                    let fmax = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    let kmax = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    let h = 1e-8;
                    let (mut fp, mut fm) = (vec![0.0; nd], vec![0.0; nd]);
                    for d in 0..nd {
                        let mut up = u0.clone();
                        up[d] += h;
                        let mut um = u0.clone();
                        um[d] -= h;
                        let ep = cell(kind, &x, &up, &law, vol, &mut s, &mut fp, None).unwrap().energy;
                        let em = cell(kind, &x, &um, &law, vol, &mut s, &mut fm, None).unwrap().energy;
                        let fd = (ep - em) / (2.0 * h);
                        assert!((fd - f[d]).abs() < 1e-5 * fmax, "{kind:?} {law:?} {vol:?} f[{d}]: {fd} vs {}", f[d]);
                        for e in 0..nd {
                            let kd = (fp[e] - fm[e]) / (2.0 * h);
                            assert!(
                                (kd - k[e * nd + d]).abs() < 1e-5 * kmax,
                                "{kind:?} {law:?} {vol:?} K[{e}][{d}]: {kd} vs {}",
                                k[e * nd + d]
                            );
                        }
                    }
                    // symmetric (it is a Hessian)
                    for a in 0..nd {
                        for b in 0..a {
                            assert!((k[a * nd + b] - k[b * nd + a]).abs() < 1e-9 * kmax);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_rigid_rotation_stores_no_energy_and_an_inversion_is_refused() {
        let x = distorted_hex();
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 1.1);
        let u: Vec<f64> = x
            .iter()
            .flat_map(|p| {
                let v = nalgebra::Vector3::from(*p);
                let w = rot * v - v;
                [w[0], w[1], w[2]]
            })
            .collect();
        let mut s = CellScratch::new(CellKind::Hex8);
        let mut f = vec![0.0; 24];
        for law in laws() {
            let st = cell(CellKind::Hex8, &x, &u, &law, Volumetric::MeanDilatation, &mut s, &mut f, None).unwrap();
            assert!(st.energy.abs() < 1e-12, "{law:?}: {}", st.energy);
            assert!(f.iter().all(|v| v.abs() < 1e-9), "{law:?}: {f:?}");
        }
        // flatten the cell through itself: top face pushed below the bottom one
        let mut u = vec![0.0; 24];
        for a in 4..8 {
            u[3 * a + 2] = -0.02;
        }
        let e = cell(CellKind::Hex8, &x, &u, &laws()[1], Volumetric::PointWise, &mut s, &mut f, None).unwrap_err();
        assert!(matches!(e, CellError::Inverted { .. }), "{e}");
    }
}
