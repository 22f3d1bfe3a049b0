//! The reduced large-deformation models where they run out (seed 001): the asymptotic series
//! of a St Venant–Kirchhoff cantilever asked for a load past its validity radius (the
//! continuation restarts the series at the radius, and must land on Newton's answer), the same
//! bar crushed past SVK's limit point in reduced coordinates (a typed stop), and the online
//! ANM-POD lattice of the cornea queried far from its positions and pressed past the end of
//! its paths (blended from the nearest positions, and continued along the last stiffness with
//! the extrapolation flagged).

use std::sync::{Arc, Mutex};

use super::{Case, Expect, Outcome, Size, diagnostic, finite, once_per_size, outcome, relative};
use crate::fem::hyperelastic::{LawMap, Volumetric};
use crate::fem::linear_static::StaticProblem;
use crate::fem::nonlinear_static::{self, NewtonParams};
use crate::material::LinearElastic;
use crate::material::hyperelastic::Hyperelastic;
use crate::mesh::{Mesh, procedural};
use crate::rom::anm::{self, AnmParams};
use crate::rom::palpation::{AnmLattice, AnmLatticeParams};
use crate::rom::pod::Pod;
use crate::rom::svk::ReducedSvk;
use crate::scene::Scene;

/// A 0.1 m × 0.02 m × 0.02 m SVK bar (E = 100 kPa, ν = 0.3) of `n × 1 × 1` hexahedra clamped
/// at x = 0, with `load` (N) spread over its tip face.
fn bar(n: usize, load: [f64; 3]) -> (Mesh, StaticProblem, LawMap, Vec<usize>) {
    let mesh = procedural::block_hex([0.0; 3], [0.1, 0.02, 0.02], [n, 1, 1]);
    let mut p = StaticProblem::new(mesh.n_nodes());
    let at = |x: f64| -> Vec<usize> { (0..mesh.n_nodes()).filter(|&a| (mesh.nodes[a][0] - x).abs() < 1e-12).collect() };
    p.clamp(&at(0.0));
    let tip = at(0.1);
    for &a in &tip {
        for i in 0..3 {
            p.forces[3 * a + i] = load[i] / tip.len() as f64;
        }
    }
    let law = Hyperelastic::svk(&LinearElastic::new(1e5, 0.3).expect("valid moduli"));
    let laws = LawMap::uniform(law, mesh.n_cells());
    (mesh, p, laws, tip)
}

/// The unit vectors of the free degrees of freedom: the reduced model is then the full one, so
/// what is measured is the series and its continuation alone.
fn full_basis(constrained: &[bool]) -> Pod {
    let n = constrained.len();
    let free: Vec<usize> = (0..n).filter(|&d| !constrained[d]).collect();
    let mut cols = vec![0.0; n * free.len()];
    for (k, &d) in free.iter().enumerate() {
        cols[k * n + d] = 1.0;
    }
    Pod::from_columns(n, cols).expect("a non-empty basis")
}

fn tip_z(u: &[f64], tip: &[usize]) -> f64 {
    tip.iter().map(|&a| u[3 * a + 2]).sum::<f64>() / tip.len() as f64
}

/// The bar bent by 2 N to a third of its length, by ANM continuation against Newton.
fn past_the_radius(size: Size) -> Outcome {
    outcome(|| {
        let (mesh, p, laws, tip) = bar(size.pick(4, 8), [0.0, 0.0, -2.0]);
        let newton =
            nonlinear_static::solve(&mesh, &laws, Volumetric::PointWise, &p, &NewtonParams::default(), |_, _| {}).map_err(diagnostic)?;
        let pod = full_basis(&p.constrained);
        let red = ReducedSvk::build(&mesh, &laws, &pod).map_err(diagnostic)?;
        let path = anm::continuation(&red, &pod.project(&p.forces), 1.0, &AnmParams::default()).map_err(diagnostic)?;
        let mut zeta = vec![0.0; pod.modes];
        if !path.at_load(1.0, &mut zeta) || !finite(&zeta) {
            return Ok(Outcome::Broken("the path does not reach the load".into()));
        }
        let mut u = vec![0.0; pod.n];
        pod.lift(&zeta, &mut u);
        let (a, b) = (tip_z(&u, &tip), tip_z(&newton.u, &tip));
        Ok(Outcome::answer(
            format!(
                "tip {:.2} mm (Newton {:.2} mm), {} series, first radius reaches load factor {:.2}",
                1e3 * a,
                1e3 * b,
                path.steps.len(),
                path.steps[0].load(path.ends[0])
            ),
            relative(a, b),
        ))
    })
}

/// The bar pushed along its axis by 4 kN: far past the peak of SVK's compressive stress.
fn crushed_reduced(_: Size) -> Outcome {
    outcome(|| {
        let (mesh, p, laws, _) = bar(4, [-4000.0, 0.0, 0.0]);
        let pod = full_basis(&p.constrained);
        let red = ReducedSvk::build(&mesh, &laws, &pod).map_err(diagnostic)?;
        let path = anm::continuation(&red, &pod.project(&p.forces), 1.0, &AnmParams::default()).map_err(diagnostic)?;
        Ok(Outcome::Broken(format!(
            "the continuation claims equilibrium at 4 kN in {} steps",
            path.steps.len()
        )))
    })
}

/// The cornea's lattice (St Venant–Kirchhoff, seed 001 §6.1), small at reduced size; built
/// once per process and size.
fn cornea_lattice(size: Size) -> Result<Arc<AnmLattice>, Outcome> {
    static BUILT: Mutex<Vec<(Size, Arc<AnmLattice>)>> = Mutex::new(Vec::new());
    once_per_size(&BUILT, size, || build_cornea_lattice(size))
}

fn build_cornea_lattice(size: Size) -> Result<AnmLattice, Outcome> {
    let scene = Scene::builtin("cornea").map_err(diagnostic)?;
    let organ = scene.organ_model(0).map_err(diagnostic)?;
    let laws = organ
        .laws
        .clone()
        .ok_or_else(|| Outcome::Broken("the cornea is not hyperelastic".into()))?;
    let large = scene.spec.fidelity.large;
    let params = AnmLatticeParams {
        positions: size.pick(3, large.positions),
        max_force: large.max_force,
        patch_radius: 1e-3,
        load_steps: size.pick(3, large.load_steps),
        modes: size.pick(4, large.modes),
        order: large.order,
    };
    AnmLattice::build(&organ, &laws, &params, |_, _| {}).map_err(diagnostic)
}

/// A depth some position's path reaches, and the deepest any reaches.
fn depths(lattice: &AnmLattice) -> (f64, f64) {
    let d = lattice.positions.iter().map(|p| p.d_linear).fold(f64::INFINITY, f64::min);
    (0.5 * d, lattice.positions.iter().map(|p| p.d_linear).fold(0.0, f64::max))
}

/// Pressed 50 cm from every position: the ratio is the nearest positions' blend, finite.
fn far_from_positions(size: Size) -> Outcome {
    outcome(|| {
        let lattice = cornea_lattice(size)?;
        let mut zeta = vec![0.0; lattice.max_modes()];
        let (depth, _) = depths(&lattice);
        let near = lattice.stiffness_ratio(lattice.positions[0].point, depth, 4, &mut zeta);
        let far = lattice.stiffness_ratio([0.5, 0.5, 0.5], depth, 4, &mut zeta);
        if !(far.ratio.is_finite() && far.ratio > 0.0) {
            return Ok(Outcome::Broken(format!("ratio {}", far.ratio)));
        }
        let (lo, hi) = lattice
            .positions
            .iter()
            .map(|p| lattice.stiffness_ratio(p.point, depth, 1, &mut zeta).ratio)
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), r| (lo.min(r), hi.max(r)));
        if !(lo * (1.0 - 1e-9)..=hi * (1.0 + 1e-9)).contains(&far.ratio) {
            return Ok(Outcome::Broken(format!("ratio {} outside the positions' {lo}…{hi}", far.ratio)));
        }
        Ok(Outcome::bounded(format!(
            "stiffening ×{:.3} (positions ×{lo:.3}…×{hi:.3}, at a position ×{:.3})",
            far.ratio, near.ratio
        )))
    })
}

/// Pressed ten times deeper than any path reaches: continued along the last stiffness, flagged.
fn beyond_paths(size: Size) -> Outcome {
    outcome(|| {
        let lattice = cornea_lattice(size)?;
        let mut zeta = vec![0.0; lattice.max_modes()];
        let (_, deepest) = depths(&lattice);
        let p = lattice.positions[0].point;
        let s = lattice.stiffness_ratio(p, 10.0 * deepest, 4, &mut zeta);
        if !(s.ratio.is_finite() && s.ratio > 0.0) {
            return Ok(Outcome::Broken(format!("ratio {}", s.ratio)));
        }
        if !s.extrapolated {
            return Ok(Outcome::Broken("pressed past every path, but not flagged as extrapolated".into()));
        }
        Ok(Outcome::bounded(format!(
            "stiffening ×{:.3} at {:.2} mm, flagged beyond range",
            s.ratio,
            1e4 * deepest
        )))
    })
}

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "a load past the series' validity radius",
            method: "ANM continuation, order 6 (reduced SVK)",
            // the series is cut where its last term is δ = 1e-6 of the first
            expect: Expect::within(1e-5),
            run: past_the_radius,
        },
        Case {
            name: "crushed past the limit point",
            method: "ANM continuation (reduced SVK)",
            expect: Expect::Diagnostic(&["limit point", "not positive definite", "validity radius fell"]),
            run: crushed_reduced,
        },
        Case {
            name: "pressed 50 cm from every lattice position",
            method: "ANM-POD lattice (cornea)",
            expect: Expect::FINITE,
            run: far_from_positions,
        },
        Case {
            name: "pressed 10× deeper than the lattice's paths",
            method: "ANM-POD lattice (cornea)",
            expect: Expect::FINITE,
            run: beyond_paths,
        },
    ]
}
