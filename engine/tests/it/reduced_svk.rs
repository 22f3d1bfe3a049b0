//! The reduced St Venant–Kirchhoff model and the asymptotic numerical method (seed 001
//! §2–4) against the full-order total Lagrangian model on the same mesh.

use std::sync::Arc;

use vademecum_engine::fem::Locking;
use vademecum_engine::fem::assembly::{DofMap, MaterialMap, SymmetricPattern, assemble_stiffness};
use vademecum_engine::fem::hyperelastic::{self, CellScratch, LawMap, Volumetric};
use vademecum_engine::fem::linear_static::StaticProblem;
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::mesh::Mesh;
use vademecum_engine::mesh::procedural::{block_hex, block_tet};
use vademecum_engine::rom::anm::{self, AnmError, AnmParams, Series};
use vademecum_engine::rom::{Pod, PodCriterion, ReducedSvk};

/// Full internal forces of an SVK mesh at `u`.
fn full_force(mesh: &Mesh, laws: &LawMap, u: &[f64]) -> Vec<f64> {
    let n = mesh.kind.nodes_per_cell();
    let mut s = CellScratch::new(mesh.kind);
    let (mut x, mut ue, mut fe) = (vec![[0.0; 3]; n], vec![0.0; 3 * n], vec![0.0; 3 * n]);
    let mut f = vec![0.0; u.len()];
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        let cell = mesh.cell(c);
        for p in 0..3 * n {
            ue[p] = u[3 * cell[p / 3] + p % 3];
        }
        hyperelastic::cell(mesh.kind, &x, &ue, laws.of(c), Volumetric::PointWise, &mut s, &mut fe, None).unwrap();
        for p in 0..3 * n {
            f[3 * cell[p / 3] + p % 3] += fe[p];
        }
    }
    f
}

/// A deterministic pseudo-random sequence in (−1, 1).
fn noise(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A bar along x, clamped at x = 0.
fn bar(mesh: Mesh) -> (Mesh, StaticProblem, Vec<bool>) {
    let clamped: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes[i][0].abs() < 1e-12).collect();
    let mut p = StaticProblem::new(mesh.n_nodes());
    p.clamp(&clamped);
    let constrained = p.constrained.clone();
    (mesh, p, constrained)
}

/// The identity basis of the free degrees of freedom: the reduced model is then the full one.
fn full_basis(constrained: &[bool]) -> Pod {
    let n = constrained.len();
    let mut cols = Vec::new();
    for (d, &c) in constrained.iter().enumerate() {
        if !c {
            let mut v = vec![0.0; n];
            v[d] = 1.0;
            cols.extend(v);
        }
    }
    Pod::from_columns(n, cols).unwrap()
}

#[test]
fn the_reduced_model_is_the_projection_of_the_full_one() {
    let mat = LinearElastic::new(1e5, 0.3).unwrap();
    let (mesh, _, constrained) = bar(block_tet([0.0; 3], [0.1, 0.02, 0.02], [5, 1, 1]));
    let laws = LawMap::uniform(Hyperelastic::svk(&mat), mesh.n_cells());
    // a POD basis of 5 random fields that vanish on the clamp
    let mut rnd = noise(7);
    let snaps: Vec<Vec<f64>> = (0..5)
        .map(|_| constrained.iter().map(|&c| if c { 0.0 } else { 0.01 * rnd() }).collect())
        .collect();
    let pod = Pod::from_snapshots(&snaps, PodCriterion::default()).unwrap();
    assert_eq!(pod.modes, 5);
    let red = ReducedSvk::build(&mesh, &laws, &pod).unwrap();

    // K₁ is the reduced linear stiffness AᵀKA of the small-strain model (same λ, μ)
    let dofs = DofMap::new(&constrained);
    let pattern = Arc::new(SymmetricPattern::build(&mesh, &dofs));
    let mut rhs = vec![0.0; dofs.n_free()];
    let materials = MaterialMap::uniform(mat, 1000.0, mesh.n_cells());
    let k = assemble_stiffness(
        &mesh,
        &materials,
        Locking::None,
        &dofs,
        pattern,
        &vec![0.0; constrained.len()],
        &mut rhs,
    )
    .unwrap();
    let k1 = pod.reduce_matrix(&dofs, &k);
    let scale = k1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in red.k1.iter().zip(&k1) {
        assert!((a - b).abs() <= 1e-10 * scale, "K1 {a} vs AᵀKA {b}");
    }

    // g(ζ) = Aᵀ f_int(Aζ) exactly (up to round-off), at strains of tens of percent
    let mut u = vec![0.0; pod.n];
    let mut g = vec![0.0; 5];
    for trial in 0..4 {
        let zeta: Vec<f64> = (0..5).map(|_| 0.002 * (1.0 + trial as f64) * rnd()).collect();
        pod.lift(&zeta, &mut u);
        let full = pod.project(&full_force(&mesh, &laws, &u));
        red.force(&zeta, &mut g);
        let norm = full.iter().map(|x| x * x).sum::<f64>().sqrt();
        for (a, b) in g.iter().zip(&full) {
            assert!((a - b).abs() <= 1e-9 * norm, "trial {trial}: reduced {a} vs projected {b}");
        }
        // the tangent is the derivative of the force, the force that of the energy
        let mut t = vec![0.0; 25];
        red.tangent(&zeta, &mut t);
        let h = 1e-6;
        for j in 0..5 {
            let (mut zp, mut zm) = (zeta.clone(), zeta.clone());
            zp[j] += h;
            zm[j] -= h;
            let (mut gp, mut gm) = (vec![0.0; 5], vec![0.0; 5]);
            red.force(&zp, &mut gp);
            red.force(&zm, &mut gm);
            let de = (red.energy(&zp) - red.energy(&zm)) / (2.0 * h);
            assert!((de - g[j]).abs() <= 1e-6 * norm, "∂Π/∂ζ_{j}: {de} vs {}", g[j]);
            for i in 0..5 {
                let fd = (gp[i] - gm[i]) / (2.0 * h);
                assert!((fd - t[i * 5 + j]).abs() <= 1e-6 * scale, "K_t[{i}][{j}]");
            }
        }
    }
}

#[test]
fn neo_hookean_is_refused_by_the_polynomial_model() {
    let mat = LinearElastic::new(1e5, 0.3).unwrap();
    let (mesh, _, constrained) = bar(block_tet([0.0; 3], [0.1, 0.02, 0.02], [2, 1, 1]));
    let laws = LawMap::uniform(Hyperelastic::neo_hookean(&mat), mesh.n_cells());
    let e = ReducedSvk::build(&mesh, &laws, &full_basis(&constrained)).unwrap_err();
    assert!(e.to_string().contains("St Venant-Kirchhoff"), "{e}");
}

/// A cantilever of SVK hexahedra bent by a transverse tip load to a deflection of about a
/// third of its length; the reduced model on the full basis is the full model.
fn cantilever(poisson: f64, load: [f64; 3]) -> (Mesh, StaticProblem, LawMap, Vec<usize>) {
    let (mesh, mut p, _) = bar(block_hex([0.0; 3], [0.1, 0.02, 0.02], [4, 1, 1]));
    let tip: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| (mesh.nodes[i][0] - 0.1).abs() < 1e-12).collect();
    for &n in &tip {
        for i in 0..3 {
            p.forces[3 * n + i] = load[i] / tip.len() as f64;
        }
    }
    let laws = LawMap::uniform(Hyperelastic::svk(&LinearElastic::new(1e5, poisson).unwrap()), mesh.n_cells());
    (mesh, p, laws, tip)
}

fn tip_mean(u: &[f64], tip: &[usize], i: usize) -> f64 {
    tip.iter().map(|&n| u[3 * n + i]).sum::<f64>() / tip.len() as f64
}

#[test]
fn anm_continuation_on_the_full_basis_follows_full_newton() {
    let (mesh, p, laws, tip) = cantilever(0.3, [0.0, 0.0, -2.0]);
    let mut snapshots = Vec::new();
    let params = NewtonParams {
        steps: 4,
        ..NewtonParams::default()
    };
    let full = nonlinear_static::solve(&mesh, &laws, Volumetric::PointWise, &p, &params, |l, u| {
        snapshots.push((l, u.to_vec()))
    })
    .unwrap();
    let deflection = tip_mean(&full.u, &tip, 2);
    assert!(deflection < -0.025, "a large deflection: {deflection} m");

    let pod = full_basis(&p.constrained);
    let red = ReducedSvk::build(&mesh, &laws, &pod).unwrap();
    let f = pod.project(&p.forces);
    let path = anm::continuation(&red, &f, 1.0, &AnmParams::default()).unwrap();
    eprintln!(
        "order 6: {} steps, radii {:?}, residuals {:?}",
        path.steps.len(),
        path.steps.iter().map(|s| s.radius).collect::<Vec<_>>(),
        path.residuals
    );
    assert!(path.steps.len() >= 2, "the load lies beyond the first validity radius");
    assert!(path.residuals.iter().all(|&r| r < 1e-4), "{:?}", path.residuals);
    let mut zeta = vec![0.0; pod.modes];
    let mut u = vec![0.0; pod.n];
    for (l, snap) in &snapshots {
        assert!(path.at_load(*l, &mut zeta));
        pod.lift(&zeta, &mut u);
        let (a, b) = (tip_mean(&u, &tip, 2), tip_mean(snap, &tip, 2));
        assert!((a - b).abs() < 1e-5 * b.abs(), "λ = {l}: ANM {a} vs Newton {b}");
    }

    // one series from the origin (seed 001 §6): exact near the origin, and converging with
    // the order at a quarter of the load, where it is within its reach
    let scale = anm::displacement_scale(&red, &f).unwrap();
    let (l4, u4) = &snapshots[0];
    let reference = tip_mean(u4, &tip, 2);
    let mut errors = Vec::new();
    for order in 1..=8 {
        let s = Series::expand(&red, &f, &vec![0.0; pod.modes], 0.0, order, scale, 1e-6).unwrap();
        let a = s.solve_load(*l4, 10.0).expect("the series reaches a quarter of the load");
        s.eval(a, &mut zeta);
        pod.lift(&zeta, &mut u);
        errors.push(((tip_mean(&u, &tip, 2) - reference) / reference).abs());
    }
    eprintln!("one series, errors at λ = {l4} by order: {errors:?}");
    assert!(errors[0] > 0.1, "the linear solution is far off at this deflection");
    assert!(errors[4] < 0.01 * errors[0] && errors[5] < 0.01 * errors[0], "{errors:?}");
}

#[test]
fn nearly_incompressible_svk_converges_in_reduced_coordinates() {
    // ν = 0.499 (λ/μ ≈ 500): the series and the continuation stay finite and match Newton
    let (mesh, p, laws, tip) = cantilever(0.499, [0.0, 0.0, -1.0]);
    let full = nonlinear_static::solve(&mesh, &laws, Volumetric::PointWise, &p, &NewtonParams::default(), |_, _| {}).unwrap();
    let pod = full_basis(&p.constrained);
    let red = ReducedSvk::build(&mesh, &laws, &pod).unwrap();
    let f = pod.project(&p.forces);
    let path = anm::continuation(&red, &f, 1.0, &AnmParams::default()).unwrap();
    let mut zeta = vec![0.0; pod.modes];
    assert!(path.at_load(1.0, &mut zeta));
    assert!(zeta.iter().all(|z| z.is_finite()));
    let mut u = vec![0.0; pod.n];
    pod.lift(&zeta, &mut u);
    let (a, b) = (tip_mean(&u, &tip, 2), tip_mean(&full.u, &tip, 2));
    eprintln!("ν = 0.499: {} steps, tip {a} m (Newton {b} m)", path.steps.len());
    assert!((a - b).abs() < 1e-4 * b.abs(), "ANM {a} vs Newton {b}");
}

#[test]
fn svk_crushed_in_reduced_coordinates_stops_with_a_diagnostic() {
    // axial compression far beyond what SVK can carry: the SVK stress peaks at a stretch of
    // 1/√3 and the bar collapses; the ANM must stop and say why, never return NaN
    let (mesh, p, laws, _) = cantilever(0.3, [-4000.0, 0.0, 0.0]);
    let pod = full_basis(&p.constrained);
    let red = ReducedSvk::build(&mesh, &laws, &pod).unwrap();
    let f = pod.project(&p.forces);
    let e = anm::continuation(&red, &f, 1.0, &AnmParams::default()).unwrap_err();
    eprintln!("{e}");
    assert!(
        matches!(
            e,
            AnmError::LimitPoint { .. } | AnmError::Unstable { .. } | AnmError::Stalled { .. }
        ),
        "{e:?}"
    );
    let lambda = match e {
        AnmError::LimitPoint { lambda, .. } | AnmError::Unstable { lambda, .. } | AnmError::Stalled { lambda, .. } => lambda,
        _ => unreachable!(),
    };
    assert!(lambda.is_finite() && lambda > 0.0 && lambda < 1.0, "stopped at {lambda}");
}

#[test]
fn seed_online_interpolation_reproduces_a_stored_model_and_ignores_basis_rotations() {
    use nalgebra::{DMatrix, DVector};
    use vademecum_engine::rom::podi_online::{Neighbourhood, StoredModel};
    let (mesh, p, laws, tip) = cantilever(0.3, [0.0, 0.0, -2.0]);
    let mut snaps = Vec::new();
    nonlinear_static::solve(&mesh, &laws, Volumetric::PointWise, &p, &NewtonParams::default(), |_, u| {
        snaps.push(u.to_vec())
    })
    .unwrap();
    let pod = Pod::from_snapshots(&snaps, PodCriterion::default()).unwrap();
    let r = pod.modes;
    let red = ReducedSvk::build(&mesh, &laws, &pod).unwrap();
    let f = pod.project(&p.forces);
    let scale = anm::displacement_scale(&red, &f).unwrap();
    let own = Series::expand(&red, &f, &vec![0.0; r], 0.0, 6, scale, 1e-6).unwrap();
    let a = DMatrix::from_column_slice(pod.n, r, &pod.basis);
    let k1 = DMatrix::from_row_slice(r, r, &red.k1);
    // the same model in a rotated, sign-flipped basis: A Q, Qᵀ K Q
    let q = {
        let (c, s) = (0.6f64, 0.8f64);
        let mut q = DMatrix::<f64>::identity(r, r);
        q[(0, 0)] = c;
        q[(0, 1)] = -s;
        q[(1, 0)] = s;
        q[(1, 1)] = c;
        q[(r - 1, r - 1)] = -1.0;
        q
    };
    let rotated = Series {
        zeta: own
            .zeta
            .chunks_exact(r)
            .flat_map(|z| (q.transpose() * DVector::from_column_slice(z)).iter().copied().collect::<Vec<_>>())
            .collect(),
        ..own.clone()
    };
    let aq = &a * &q;
    let kq = q.transpose() * &k1 * &q;
    let fq: Vec<f64> = (q.transpose() * DVector::from_column_slice(&f)).iter().copied().collect();
    let stored = StoredModel::new(a.clone(), k1, &f, &own);
    let stored_q = StoredModel::new(aq.clone(), kq, &fq, &rotated);
    // K on the free dofs
    let mat = LinearElastic::new(1e5, 0.3).unwrap();
    let dofs = DofMap::new(&p.constrained);
    let pattern = Arc::new(SymmetricPattern::build(&mesh, &dofs));
    let mut rhs = vec![0.0; dofs.n_free()];
    let k = assemble_stiffness(
        &mesh,
        &MaterialMap::uniform(mat, 1000.0, mesh.n_cells()),
        Locking::None,
        &dofs,
        pattern,
        &vec![0.0; p.constrained.len()],
        &mut rhs,
    )
    .unwrap();
    let fv = DVector::from_column_slice(&p.forces);
    let probe_of = |b: &DMatrix<f64>| DVector::from_fn(r, |j, _| tip.iter().map(|&n| b[(3 * n + 2, j)]).sum::<f64>() / tip.len() as f64);
    let tip_at = |s: &Series, probe: &DVector<f64>, lambda: f64| {
        let a = s.solve_load(lambda, 8.0).unwrap();
        let mut z = vec![0.0; r];
        s.eval(a, &mut z);
        probe.iter().zip(&z).map(|(p, z)| p * z).sum::<f64>()
    };
    let reference = tip_at(&own, &probe_of(&a), 0.5);
    // one stored model, weight 1: its own series back
    let one = Neighbourhood::new(vec![stored.clone()], &dofs, &k).unwrap();
    let (s1, pr1) = one.series(&[1.0], &[a.transpose() * &fv], &[probe_of(&a)], 6, 1e-6).unwrap();
    for (x, y) in s1.lambda.iter().zip(&own.lambda) {
        assert!((x - y).abs() < 1e-9 * (1.0 + y.abs()), "λ_p {x} vs {y}");
    }
    assert!((tip_at(&s1, &pr1, 0.5) - reference).abs() < 1e-9 * reference.abs());
    // the same model twice, once rotated, half and half: the same displacement
    let two = Neighbourhood::new(vec![stored, stored_q], &dofs, &k).unwrap();
    let (s2, pr2) = two
        .series(
            &[0.5, 0.5],
            &[a.transpose() * &fv, aq.transpose() * &fv],
            &[probe_of(&a), probe_of(&aq)],
            6,
            1e-6,
        )
        .unwrap();
    let d2 = tip_at(&s2, &pr2, 0.5);
    assert!((d2 - reference).abs() < 1e-8 * reference.abs(), "{d2} vs {reference}");
}
