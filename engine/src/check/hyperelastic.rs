//! Every hyperelastic law at large strains, against the exact homogeneous answer: a 0.1 m
//! cube on three symmetry rollers, its top face pulled to twice its height or pushed to half of
//! it. The state is uniaxial and homogeneous, so every element reproduces it exactly: the exact
//! reaction is `A₀ P₂₂ = A₀ λ S₂₂(C)` with `C = diag(a², λ², a²)` and the lateral stretch `a`
//! the root of `S₁₁ = 0`, found by bisection on the law's own stress. The error then measures
//! Newton's solve alone. Then what no law can do: a cube pushed through itself (inversion:
//! Newton's typed diagnostic) and St Venant–Kirchhoff crushed to a fifth (its stress vanishes
//! again under full collapse: an answer or the diagnostic, never NaN).

use nalgebra::Matrix3;

use super::{Case, Expect, Outcome, Size, diagnostic, finite, outcome, relative};
use crate::fem::hyperelastic::{LawMap, Volumetric};
use crate::fem::linear_static::StaticProblem;
use crate::fem::nonlinear_static::{self, NewtonParams};
use crate::material::LinearElastic;
use crate::material::hyperelastic::{Hyperelastic, Part, VolumetricLaw};
use crate::mesh::{CellKind, Mesh, procedural};

/// Edge of the cube (m).
const EDGE: f64 = 0.1;

/// Soft tissue: E = 3 kPa with Poisson's ratio `nu`.
fn tissue(nu: f64) -> LinearElastic {
    LinearElastic::new(3000.0, nu).expect("valid moduli")
}

/// The law named `name` (`svk`, `nh`, `mr`) with `U(J)` = `vol` for tissue of ratio `nu`
/// (Mooney–Rivlin: a quarter of the shear modulus in C₀₁).
fn law(name: &str, vol: VolumetricLaw, nu: f64) -> Hyperelastic {
    let m = tissue(nu);
    let mut law = match name {
        "svk" => Hyperelastic::svk(&m),
        "nh" => Hyperelastic::neo_hookean(&m),
        _ => Hyperelastic::mooney_rivlin(&m, 0.25).expect("valid moduli"),
    };
    if let Hyperelastic::NeoHookean { volumetric, .. } | Hyperelastic::MooneyRivlin { volumetric, .. } = &mut law {
        *volumetric = vol;
    }
    law
}

/// The exact reaction on the pulled face of the uniaxial cube at axial stretch `stretch`.
fn uniaxial_reaction(law: &Hyperelastic, stretch: f64) -> Option<f64> {
    let s = |a: f64| {
        let c = Matrix3::from_diagonal(&nalgebra::Vector3::new(a * a, stretch * stretch, a * a));
        law.response(&c, Part::Full).map(|r| r.stress)
    };
    // S₁₁ grows with the lateral stretch: bracket its root and bisect
    let (mut lo, mut hi) = (1e-3, 1e3);
    if !(s(lo)?[0] < 0.0 && s(hi)?[0] > 0.0) {
        return None;
    }
    for _ in 0..200 {
        let mid = (lo * hi).sqrt();
        if s(mid)?[0] < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(EDGE * EDGE * stretch * s(lo)?[1])
}

fn cube(kind: CellKind, n: usize) -> Mesh {
    match kind {
        CellKind::Hex8 => procedural::block_hex([0.0; 3], [EDGE; 3], [n; 3]),
        CellKind::Tet4 => procedural::block_tet([0.0; 3], [EDGE; 3], [n; 3]),
    }
}

/// The top face `y = EDGE` moved by `dy`; the other faces on rollers (`clamped`: the bottom
/// face held in all directions instead, the sides free).
fn pulled(mesh: &Mesh, dy: f64, clamped: bool) -> (StaticProblem, Vec<usize>) {
    let mut p = StaticProblem::new(mesh.n_nodes());
    let on = |a: usize, i: usize, v: f64| (mesh.nodes[a][i] - v).abs() < 1e-12;
    let top: Vec<usize> = (0..mesh.n_nodes()).filter(|&a| on(a, 1, EDGE)).collect();
    for a in 0..mesh.n_nodes() {
        if clamped && on(a, 1, 0.0) {
            p.clamp(&[a]);
        }
        for i in 0..3 {
            if !clamped && on(a, i, 0.0) {
                p.prescribe(&[a], i, 0.0);
            }
        }
    }
    p.prescribe(&top, 1, dy);
    if clamped {
        p.prescribe(&top, 0, 0.0);
        p.prescribe(&top, 2, 0.0);
    }
    (p, top)
}

/// The cube of `kind` with `law` stretched to `stretch` on rollers, against the exact reaction.
fn uniaxial(size: Size, kind: CellKind, volumetric: Volumetric, law: Hyperelastic, stretch: f64) -> Outcome {
    outcome(|| {
        // St Venant–Kirchhoff has none in strong tension: its lateral stress cannot vanish
        // (a² = 1 − λ(λ² − 1)/2(λ + μ) < 0); Newton must then stop and say so
        let exact = uniaxial_reaction(&law, stretch);
        let mesh = cube(kind, size.pick(2, 4));
        let (p, top) = pulled(&mesh, EDGE * (stretch - 1.0), false);
        let laws = LawMap::uniform(law, mesh.n_cells());
        let params = NewtonParams {
            steps: 8,
            ..NewtonParams::default()
        };
        let s = nonlinear_static::solve(&mesh, &laws, volumetric, &p, &params, |_, _| {}).map_err(|e| match exact {
            Some(_) => diagnostic(e),
            None => Outcome::Diagnostic(format!("{e} (no homogeneous uniaxial state exists at this stretch)")),
        })?;
        let f = s.reaction_sum(&top)[1];
        let Some(exact) = exact else {
            return Ok(Outcome::bounded(format!(
                "no homogeneous uniaxial state exists; Newton found another equilibrium, {f:.2} N"
            )));
        };
        if !(finite(&s.u) && f.is_finite()) {
            return Ok(Outcome::Broken(format!("reaction {f} N")));
        }
        Ok(Outcome::answer(
            format!("reaction {f:.4} N (exact {exact:.4} N), {} Newton steps", s.info.steps),
            relative(f, exact),
        ))
    })
}

/// The cube clamped at its base with its top face moved to `stretch` of its height.
fn crushed(law: Hyperelastic, stretch: f64) -> Outcome {
    outcome(|| {
        let mesh = cube(CellKind::Hex8, 2);
        let (p, top) = pulled(&mesh, EDGE * (stretch - 1.0), true);
        let laws = LawMap::uniform(law, mesh.n_cells());
        let s = nonlinear_static::solve(&mesh, &laws, Volumetric::MeanDilatation, &p, &NewtonParams::default(), |_, _| {})
            .map_err(diagnostic)?;
        let f = s.reaction_sum(&top)[1];
        if !(finite(&s.u) && f.is_finite() && s.energy.is_finite()) {
            return Ok(Outcome::Broken(format!("reaction {f} N, energy {} J", s.energy)));
        }
        Ok(Outcome::bounded(format!("reaction {f:.4} N, energy {:.3e} J", s.energy)))
    })
}

pub(super) fn cases() -> Vec<Case> {
    use CellKind::{Hex8, Tet4};
    use Volumetric::{MeanDilatation, Nodal, PointWise};
    use VolumetricLaw::{JMinus1, LnJ, SimoTaylor};
    // Newton stops at a relative residual of 1e-9: the reaction is as exact as that
    const EXACT: Expect = Expect::within(1e-6);
    const NO_EQUILIBRIUM: &[&str] = &["no equilibrium beyond load factor"];
    macro_rules! law_case {
        ($name:literal, $method:literal, $l:literal, $v:expr, $stretch:literal, $expect:expr) => {
            Case {
                name: $name,
                method: $method,
                expect: $expect,
                run: |s| uniaxial(s, Hex8, MeanDilatation, law($l, $v, 0.45), $stretch),
            }
        };
    }
    // each law and volumetric penalty on one load; St Venant–Kirchhoff first, with what it
    // may answer there
    macro_rules! every_law {
        ($name:literal, $stretch:literal, $svk:expr) => {
            [
                law_case!($name, "St Venant–Kirchhoff, hex8", "svk", JMinus1, $stretch, $svk),
                law_case!(
                    $name,
                    "neo-Hookean K/2 (J − 1)², hex8 mean dilatation",
                    "nh",
                    JMinus1,
                    $stretch,
                    EXACT
                ),
                law_case!(
                    $name,
                    "neo-Hookean K/2 (ln J)², hex8 mean dilatation",
                    "nh",
                    LnJ,
                    $stretch,
                    EXACT
                ),
                law_case!(
                    $name,
                    "neo-Hookean Simo–Taylor, hex8 mean dilatation",
                    "nh",
                    SimoTaylor,
                    $stretch,
                    EXACT
                ),
                law_case!(
                    $name,
                    "Mooney–Rivlin K/2 (J − 1)², hex8 mean dilatation",
                    "mr",
                    JMinus1,
                    $stretch,
                    EXACT
                ),
                law_case!(
                    $name,
                    "Mooney–Rivlin K/2 (ln J)², hex8 mean dilatation",
                    "mr",
                    LnJ,
                    $stretch,
                    EXACT
                ),
                law_case!(
                    $name,
                    "Mooney–Rivlin Simo–Taylor, hex8 mean dilatation",
                    "mr",
                    SimoTaylor,
                    $stretch,
                    EXACT
                ),
            ]
        };
    }
    let stretched = every_law!(
        "100 % stretch, ν = 0.45",
        2.0,
        Expect::AnswerOrDiagnostic(&["no homogeneous uniaxial state exists"])
    );
    let compressed = every_law!("50 % compression, ν = 0.45", 0.5, Expect::AnswerOrDiagnostic(NO_EQUILIBRIUM));
    stretched
        .into_iter()
        .chain(compressed)
        .chain([
            Case {
                name: "100 % stretch, ν = 0.4999",
                method: "neo-Hookean, hex8 full integration",
                expect: EXACT,
                run: |s| uniaxial(s, Hex8, PointWise, law("nh", JMinus1, 0.4999), 2.0),
            },
            Case {
                name: "100 % stretch, ν = 0.4999",
                method: "neo-Hookean, hex8 mean dilatation",
                expect: EXACT,
                run: |s| uniaxial(s, Hex8, MeanDilatation, law("nh", JMinus1, 0.4999), 2.0),
            },
            Case {
                name: "100 % stretch, ν = 0.4999",
                method: "neo-Hookean, tet4 averaged nodal pressure",
                expect: EXACT,
                run: |s| uniaxial(s, Tet4, Nodal, law("nh", JMinus1, 0.4999), 2.0),
            },
            Case {
                name: "pushed through itself (120 %)",
                method: "neo-Hookean, Newton–Raphson",
                expect: Expect::Diagnostic(NO_EQUILIBRIUM),
                run: |_| crushed(law("nh", JMinus1, 0.45), -0.2),
            },
            Case {
                name: "crushed to 20 % of its height",
                method: "St Venant–Kirchhoff, Newton–Raphson",
                expect: Expect::AnswerOrDiagnostic(NO_EQUILIBRIUM),
                run: |_| crushed(law("svk", JMinus1, 0.3), 0.2),
            },
        ])
        .collect()
}
