//! Reduced models on a lattice of load positions, and their interpolation to positions off the
//! lattice, measured against the full model there (seed 001 §5–6).
//!
//! # The study
//! The lattice is a square grid of `n × n` positions in the plane orthogonal to the load,
//! centred on the scene's load point, each snapped to the nearest accessible surface node; the
//! load at a position is the scene's total force spread over the accessible nodes within the
//! tool's radius of it (at least the nearest one). Each lattice position gets a full
//! Newton–Raphson path and its POD basis. At every test position (the midpoints of the lattice
//! cells and edges), the bases of the four nearest lattice positions are interpolated with
//! inverse-distance weights — nearest neighbour only, PODI, Grassmann — and the reduced St
//! Venant–Kirchhoff model in each interpolated basis is followed by ANM continuation to the
//! full load, and compared with full Newton at that position. The projection error of the test
//! position's own Newton states on the interpolated basis tells how well the subspace itself
//! was predicted. A fourth basis, the POD of the four neighbours' snapshots
//! (each set weighted by `√w_k`, the standard PODI of the seed's Ref. 28), shows what a basis
//! spanning the neighbourhood gains over interpolating one-position bases.

use nalgebra::{DMatrix, DVector};

use super::anm::{self, AnmParams};
use super::interpolate::{self, InterpolationError};
use super::palpation::{AnmLattice, AnmLatticeParams, AnmPosition};
use super::pod::{Pod, PodCriterion};
use super::podi_online::{Neighbourhood, StoredModel};
use super::study::StudyError;
use super::svk::ReducedSvk;
use super::unit;
use crate::fem::Locking;
use crate::fem::assembly::{DofMap, MaterialMap, SymmetricMatrix, SymmetricPattern, assemble_stiffness};
use crate::fem::hyperelastic::{LawMap, Volumetric};
use crate::fem::linear_static::StaticProblem;
use crate::fem::nonlinear_static::{self, NewtonParams};
use crate::mesh::Mesh;
use crate::solve::Cholesky;

/// Settings of the lattice study.
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeParams {
    /// Positions per side of the lattice.
    pub side: usize,
    /// Spacing between lattice positions (m).
    pub spacing: f64,
    /// Radius of the loaded patch around a position (m).
    pub patch_radius: f64,
    /// Newton load steps per position (snapshots).
    pub load_steps: usize,
    /// POD modes.
    pub pod: PodCriterion,
    /// Neighbours interpolated.
    pub neighbours: usize,
    /// Add to each position's snapshots the linear responses (tangent at the origin) to the
    /// same load at every accessible node within one spacing, scaled to the size of its own
    /// path: a basis that spans the loads around its position, not only its own.
    pub enrich: bool,
}

impl Default for LatticeParams {
    /// A 3 × 3 lattice, 6 load steps, 9 modes at most, four neighbours (seed 001 §6.1).
    fn default() -> Self {
        Self {
            side: 3,
            spacing: 0.01,
            patch_radius: 0.0,
            load_steps: 6,
            pod: PodCriterion {
                energy: 1.0 - 1e-12,
                max_modes: 9,
            },
            neighbours: 4,
            enrich: false,
        }
    }
}

/// One load position.
#[derive(Debug, Clone)]
pub struct Position {
    /// Where it was asked for (m).
    pub requested: [f64; 3],
    /// The loaded nodes.
    pub nodes: Vec<usize>,
    /// Their centroid (m).
    pub centre: [f64; 3],
    /// Full Newton: `(λ, displacement under the load along it)`.
    pub newton: Vec<(f64, f64)>,
    /// The POD basis of its Newton states.
    pub basis: DMatrix<f64>,
    /// Its Newton states (the snapshots).
    pub snapshots: Vec<Vec<f64>>,
    /// Its ANM-POD force–depth law as a session serves it.
    pub served: AnmPosition,
}

/// The errors at one test position.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TestRow {
    /// The position (m).
    pub centre: [f64; 3],
    /// Distance to the nearest lattice position (m).
    pub nearest_m: f64,
    /// Full Newton under the load at `λ = 1` (m).
    pub newton: f64,
    /// Per method (nearest, PODI, Grassmann, snapshot POD): relative error of the displacement under the
    /// load at `λ = 1` against full Newton at this position.
    pub error: [f64; 4],
    /// Per method: the relative projection error `‖S − AAᵀS‖/‖S‖` (Frobenius) of the
    /// position's own Newton states `S` on the basis: how well the subspace was predicted.
    pub projection: [f64; 4],
    /// Why a method gave no result (its error is then infinite).
    pub failures: Vec<String>,
    /// Relative error of the neighbours' responses blended with the same weights (their
    /// displacements under their own loads at `λ = 1`).
    pub response_error: f64,
    /// What a session serves ([`super::palpation`]): the relative error of the force at this
    /// position's full-load depth when the neighbours' nonlinear/linear force ratios are blended
    /// and multiplied by this position's exact linear force.
    pub served_error: f64,
    /// The size of the nonlinear correction there, `|ratio − 1|` (what ignoring it would cost).
    pub correction: f64,
    /// Seed 001 §5 as published, online ([`super::podi_online`]): PODI basis, interpolated
    /// tangent, load and nonlinear terms, one order-6 series — relative error at full load.
    pub online_error: f64,
    /// Its cost for this evaluation (µs, one call: a figure, not a benchmark).
    pub online_us: f64,
}

/// Order of the series of the seed's online interpolation.
const ONLINE_ORDER: usize = 6;

/// The lattice study's result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LatticeStudy {
    /// Lattice positions actually used (node-snapped centroids, m).
    pub lattice: Vec<[f64; 3]>,
    /// Modes per basis.
    pub modes: usize,
    /// One row per test position.
    pub rows: Vec<TestRow>,
    /// The error of the position's own POD basis (the floor the interpolation aims at).
    pub own_basis_error: Vec<f64>,
}

/// Method names in the order of [`TestRow::error`].
pub const METHODS: [&str; 4] = ["nearest", "PODI", "Grassmann", "snapshot POD"];

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// Two unit vectors spanning the plane orthogonal to `d`.
fn plane(d: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let a = if d[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let dot: f64 = (0..3).map(|k| a[k] * d[k]).sum();
    let e1 = unit([a[0] - dot * d[0], a[1] - dot * d[1], a[2] - dot * d[2]]).expect("not parallel");
    let e2 = [
        d[1] * e1[2] - d[2] * e1[1],
        d[2] * e1[0] - d[0] * e1[2],
        d[0] * e1[1] - d[1] * e1[0],
    ];
    (e1, e2)
}

struct Setup<'a> {
    linear: Option<(DofMap, Cholesky)>,
    mesh: &'a Mesh,
    laws: &'a LawMap,
    base: &'a StaticProblem,
    accessible: &'a [usize],
    force: [f64; 3],
    direction: [f64; 3],
    params: &'a LatticeParams,
}

impl Setup<'_> {
    /// The accessible node nearest to `p` in the plane orthogonal to the load (the surface
    /// point the tool reaches there), and the patch around it.
    fn patch(&self, p: [f64; 3]) -> Vec<usize> {
        let d = self.direction;
        let lateral = |q: [f64; 3]| {
            let v = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let along: f64 = (0..3).map(|k| v[k] * d[k]).sum();
            (0..3).map(|k| (v[k] - along * d[k]).powi(2)).sum::<f64>().sqrt()
        };
        let nodes = &self.mesh.nodes;
        let Some(&hit) = self
            .accessible
            .iter()
            .min_by(|&&a, &&b| lateral(nodes[a]).total_cmp(&lateral(nodes[b])))
        else {
            return Vec::new();
        };
        let mut patch: Vec<usize> = self
            .accessible
            .iter()
            .copied()
            .filter(|&n| dist(nodes[n], nodes[hit]) <= self.params.patch_radius)
            .collect();
        if patch.is_empty() {
            patch.push(hit);
        }
        patch
    }

    fn problem(&self, patch: &[usize]) -> StaticProblem {
        let mut p = self.base.clone();
        p.forces.fill(0.0);
        crate::fem::loads::add_distributed_force(&mut p.forces, patch, self.force);
        p
    }

    fn under(&self, patch: &[usize], u: &[f64]) -> f64 {
        super::mean_along(u, patch, self.direction)
    }

    fn position(&self, requested: [f64; 3]) -> Result<Position, StudyError> {
        let nodes = self.patch(requested);
        if nodes.is_empty() {
            return Err(StudyError::Unsupported("the organ has no accessible node".into()));
        }
        let problem = self.problem(&nodes);
        let mut snaps = Vec::new();
        let mut newton = Vec::new();
        let params = NewtonParams {
            steps: self.params.load_steps.max(1),
            ..NewtonParams::default()
        };
        nonlinear_static::solve(self.mesh, self.laws, Volumetric::PointWise, &problem, &params, |l, u| {
            newton.push((l, self.under(&nodes, u)));
            snaps.push(u.to_vec());
        })?;
        let hit = nodes[0];
        let served = AnmLattice::position(
            self.mesh,
            self.laws,
            &nodes,
            self.base,
            &AnmLatticeParams {
                positions: 1,
                max_force: self.force.iter().map(|x| x * x).sum::<f64>().sqrt(),
                patch_radius: f64::INFINITY,
                load_steps: self.params.load_steps,
                modes: self.params.pod.max_modes,
                order: AnmParams::default().order,
            },
            hit,
            self.direction,
        )?;
        let size = snaps.last().map_or(0.0, |u| u.iter().map(|x| x * x).sum::<f64>().sqrt());
        snaps.extend(self.linear_responses(&nodes, size));
        let pod = Pod::from_snapshots(&snaps, self.params.pod)?;
        let centre = {
            let mut c = [0.0; 3];
            for &n in &nodes {
                for k in 0..3 {
                    c[k] += self.mesh.nodes[n][k] / nodes.len() as f64;
                }
            }
            c
        };
        Ok(Position {
            requested,
            basis: DMatrix::from_column_slice(pod.n, pod.modes, &pod.basis),
            nodes,
            centre,
            newton,
            snapshots: snaps,
            served,
        })
    }

    /// The linear responses to the load on each accessible node within one spacing of the
    /// patch (when enriching), each scaled to norm `size`.
    fn linear_responses(&self, patch: &[usize], size: f64) -> Vec<Vec<f64>> {
        let Some((dofs, chol)) = &self.linear else {
            return Vec::new();
        };
        let nodes = &self.mesh.nodes;
        let around: Vec<usize> = self
            .accessible
            .iter()
            .copied()
            .filter(|&n| !patch.contains(&n) && patch.iter().any(|&p| dist(nodes[n], nodes[p]) <= self.params.spacing))
            .collect();
        let nf = dofs.n_free();
        let mut rhs = vec![0.0; nf * around.len()];
        for (c, &n) in around.iter().enumerate() {
            let mut f = vec![0.0; 3 * self.mesh.n_nodes()];
            crate::fem::loads::add_point_force(&mut f, n, self.force);
            dofs.restrict(&f, &mut rhs[c * nf..(c + 1) * nf]);
        }
        chol.solve_many_in_place(&mut rhs, around.len());
        let zero = vec![0.0; 3 * self.mesh.n_nodes()];
        rhs.chunks_exact(nf)
            .map(|col| {
                let mut u = vec![0.0; zero.len()];
                dofs.expand(col, &zero, &mut u);
                let norm = u.iter().map(|x| x * x).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
                u.iter_mut().for_each(|x| *x *= size / norm);
                u
            })
            .collect()
    }

    /// Displacement under the load at `λ = 1` of the reduced model in basis `a`.
    fn reduced_at_full_load(&self, a: &DMatrix<f64>, nodes: &[usize]) -> Result<f64, StudyError> {
        let pod = Pod::from_columns(a.nrows(), a.as_slice().to_vec())?;
        let model = ReducedSvk::build(self.mesh, self.laws, &pod)?;
        let problem = self.problem(nodes);
        let f = pod.project(&problem.forces);
        let path = anm::continuation(&model, &f, 1.0, &AnmParams::default())?;
        let mut zeta = vec![0.0; pod.modes];
        if !path.at_load(1.0, &mut zeta) {
            return Err(StudyError::Unsupported("the continuation did not reach the full load".into()));
        }
        let mut u = vec![0.0; pod.n];
        pod.lift(&zeta, &mut u);
        Ok(self.under(nodes, &u))
    }
}

/// `‖S − AAᵀS‖_F / ‖S‖_F` for the snapshots `S` and orthonormal `a`.
fn projection_error(a: &DMatrix<f64>, snapshots: &[Vec<f64>]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for s in snapshots {
        let v = nalgebra::DVector::from_column_slice(s);
        let rest = &v - a * (a.transpose() * &v);
        num += rest.norm_squared();
        den += v.norm_squared();
    }
    (num / den.max(f64::MIN_POSITIVE)).sqrt()
}

/// The bases interpolated at the `test` position from its `order`ed neighbours with
/// `weights` — nearest neighbour, PODI, Grassmann, and the POD of the neighbours' snapshots
/// weighted by `√w_k` — each with the relative error of its reduced model at full load against
/// full Newton (`newton`) and the projection error of the position's own snapshots on it; and
/// what failed.
fn interpolated_errors(
    setup: &Setup<'_>,
    lattice: &[Position],
    order: &[usize],
    weights: &[f64],
    test: &Position,
    modes: usize,
    newton: f64,
) -> ([f64; 4], [f64; 4], Vec<String>) {
    let bases: Vec<DMatrix<f64>> = order.iter().map(|&k| lattice[k].basis.clone()).collect();
    // the POD of the neighbours' snapshots, each set weighted by √w_k
    let pooled: Vec<Vec<f64>> = order
        .iter()
        .zip(weights)
        .filter(|&(_, &w)| w > 0.0)
        .flat_map(|(&k, &w)| lattice[k].snapshots.iter().map(move |s| s.iter().map(|x| w.sqrt() * x).collect()))
        .collect();
    let pooled = Pod::from_snapshots(
        &pooled,
        PodCriterion {
            energy: 1.0,
            max_modes: modes,
        },
    )
    .map(|p| DMatrix::from_column_slice(p.n, p.modes, &p.basis))
    .map_err(|_| InterpolationError::Weights);
    let candidates: [Result<DMatrix<f64>, InterpolationError>; 4] = [
        Ok(bases[0].clone()),
        interpolate::podi(&bases, weights),
        interpolate::grassmann(&bases, weights),
        pooled,
    ];
    let mut error = [f64::INFINITY; 4];
    let mut failures = Vec::new();
    let mut projection = [f64::NAN; 4];
    for (m, c) in candidates.into_iter().enumerate() {
        let Ok(a) = c else { continue };
        projection[m] = projection_error(&a, &test.snapshots);
        match setup.reduced_at_full_load(&a, &test.nodes) {
            Ok(d) => error[m] = ((d - newton) / newton).abs(),
            Err(e) => failures.push(format!("{}: {e}", METHODS[m])),
        }
    }
    (error, projection, failures)
}

/// The models seed 001 §5 stores at each lattice position for its online interpolation: the
/// position's basis (its first `modes`), reduced tangent, load and its own ANM series.
fn stored_models(setup: &Setup<'_>, lattice: &[Position], modes: usize) -> Result<Vec<StoredModel>, StudyError> {
    let mut stored = Vec::with_capacity(lattice.len());
    for p in lattice {
        let pod = Pod::from_columns(p.basis.nrows(), p.basis.as_slice().to_vec())?;
        let model = ReducedSvk::build(setup.mesh, setup.laws, &pod)?;
        let f = pod.project(&setup.problem(&p.nodes).forces);
        let scale = anm::displacement_scale(&model, &f)?;
        let series = anm::Series::expand(&model, &f, &vec![0.0; modes], 0.0, ONLINE_ORDER, scale, 1e-6)?;
        stored.push(StoredModel::new(
            p.basis.clone(),
            DMatrix::from_row_slice(modes, modes, &model.k1),
            &f,
            &series,
        ));
    }
    Ok(stored)
}

/// Seed 001 §5 online at the `test` position: the PODI basis of its `order`ed neighbours'
/// `stored` models with `weights`, the interpolated tangent, load and nonlinear terms, one ANM
/// series to the full load; its relative error against full Newton there and its time (µs).
/// What fails is added to `failures` (the error is then infinite).
fn online_at(
    setup: &Setup<'_>,
    lattice: &[Position],
    stored: &[StoredModel],
    order: &[usize],
    weights: &[f64],
    test: &Position,
    (dofs, stiffness): (&DofMap, &SymmetricMatrix),
    modes: usize,
    failures: &mut Vec<String>,
) -> Result<(f64, f64), StudyError> {
    let newton = test.newton.last().map_or(0.0, |&(_, d)| d);
    let hood = Neighbourhood::new(order.iter().map(|&k| stored[k].clone()).collect(), dofs, stiffness)
        .map_err(|e| StudyError::Unsupported(e.to_string()))?;
    let f_test = setup.problem(&test.nodes).forces;
    let loads: Vec<DVector<f64>> = order
        .iter()
        .map(|&k| lattice[k].basis.transpose() * DVector::from_column_slice(&f_test))
        .collect();
    let probes: Vec<DVector<f64>> = order
        .iter()
        .map(|&k| {
            let b = &lattice[k].basis;
            DVector::from_fn(b.ncols(), |j, _| {
                super::mean_along(b.column(j).as_slice(), &test.nodes, setup.direction)
            })
        })
        .collect();
    let clock = std::time::Instant::now();
    let online = hood.series(weights, &loads, &probes, ONLINE_ORDER, 1e-6).map(|(s, probe)| {
        let mut z = vec![0.0; modes];
        s.solve_load(1.0, 8.0).map(|a| {
            s.eval(a, &mut z);
            probe.iter().zip(&z).map(|(p, z)| p * z).sum::<f64>()
        })
    });
    let online_us = clock.elapsed().as_secs_f64() * 1e6;
    let online_error = match online {
        Ok(Some(d)) => ((d - newton) / newton).abs(),
        Ok(None) => {
            failures.push("seed §5 online: the series does not reach the full load".into());
            f64::INFINITY
        }
        Err(e) => {
            failures.push(format!("seed §5 online: {e}"));
            f64::INFINITY
        }
    };
    Ok((online_error, online_us))
}

/// Runs the lattice study for the load case `base` (its supports; its forces give the load
/// point and the total force) on the accessible nodes; `progress` gets a stage label.
pub fn interpolation_study(
    mesh: &Mesh,
    laws: &LawMap,
    materials: &MaterialMap,
    base: &StaticProblem,
    accessible: &[usize],
    params: &LatticeParams,
    mut progress: impl FnMut(&str),
) -> Result<LatticeStudy, StudyError> {
    if params.side < 2 || params.neighbours == 0 || !(params.spacing.is_finite() && params.spacing > 0.0) {
        return Err(StudyError::Unsupported(
            "the lattice needs at least 2 positions per side, a positive spacing and a neighbour".into(),
        ));
    }
    let n = base.forces.len() / 3;
    let loaded: Vec<usize> = (0..n).filter(|&i| (0..3).any(|k| base.forces[3 * i + k] != 0.0)).collect();
    let mut force = [0.0; 3];
    let mut centre = [0.0; 3];
    for &i in &loaded {
        for k in 0..3 {
            force[k] += base.forces[3 * i + k];
            centre[k] += mesh.nodes[i][k] / loaded.len() as f64;
        }
    }
    let direction = unit(force).ok_or_else(|| StudyError::Unsupported("the load case has no force".into()))?;
    if base.springs.iter().any(|&k| k != 0.0) || !base.pressures.is_empty() {
        return Err(StudyError::Unsupported(
            "the large-deformation lattice does not take elastic foundations or pressures yet; use rigid supports and point loads".into(),
        ));
    }
    progress("tangent stiffness at the origin");
    let dofs = DofMap::new(&base.constrained);
    let pattern = std::sync::Arc::new(SymmetricPattern::build(mesh, &dofs));
    let mut rhs = vec![0.0; dofs.n_free()];
    let stiffness = assemble_stiffness(mesh, materials, Locking::None, &dofs, pattern, &base.prescribed, &mut rhs)
        .map_err(|e| StudyError::Unsupported(e.to_string()))?;
    let linear = if params.enrich {
        let chol = Cholesky::factor(&stiffness).map_err(|e| StudyError::Unsupported(e.to_string()))?;
        Some((dofs.clone(), chol))
    } else {
        None
    };
    let setup = Setup {
        linear,
        mesh,
        laws,
        base,
        accessible,
        force,
        direction,
        params,
    };
    let (e1, e2) = plane(direction);
    let half = (params.side - 1) as f64 / 2.0;
    let at = |i: f64, j: f64| -> [f64; 3] {
        let (x, y) = ((i - half) * params.spacing, (j - half) * params.spacing);
        [0, 1, 2].map(|k| centre[k] + x * e1[k] + y * e2[k])
    };
    let mut lattice = Vec::new();
    for j in 0..params.side {
        for i in 0..params.side {
            progress(&format!("lattice position {} of {}", lattice.len() + 1, params.side * params.side));
            lattice.push(setup.position(at(i as f64, j as f64))?);
        }
    }
    let modes = lattice.iter().map(|p| p.basis.ncols()).min().unwrap_or(0);
    for p in &mut lattice {
        p.basis = p.basis.columns(0, modes).into_owned();
    }
    // the stored models of seed 001 §5 online: tangent, own series and its nonlinear terms
    let stored = stored_models(&setup, &lattice, modes)?;
    // test positions: cell centres, then midpoints of the edges of the central cell
    let mut tests = Vec::new();
    for j in 0..params.side - 1 {
        for i in 0..params.side - 1 {
            tests.push(at(i as f64 + 0.5, j as f64 + 0.5));
        }
    }
    tests.push(at(half.floor() + 0.5, half.floor()));
    tests.push(at(half.floor(), half.floor() + 0.5));
    let mut rows = Vec::new();
    let mut own_basis_error = Vec::new();
    for (t, p) in tests.iter().enumerate() {
        progress(&format!("test position {} of {}", t + 1, tests.len()));
        let test = setup.position(*p)?;
        let own = test.basis.columns(0, modes.min(test.basis.ncols())).into_owned();
        let newton = test.newton.last().map_or(0.0, |&(_, d)| d);
        let mut order: Vec<usize> = (0..lattice.len()).collect();
        order.sort_by(|&a, &b| dist(lattice[a].centre, test.centre).total_cmp(&dist(lattice[b].centre, test.centre)));
        order.truncate(params.neighbours.min(lattice.len()));
        let distances: Vec<f64> = order.iter().map(|&k| dist(lattice[k].centre, test.centre)).collect();
        let weights = interpolate::inverse_distance_weights(&distances);
        let (error, projection, mut failures) = interpolated_errors(&setup, &lattice, &order, &weights, &test, modes, newton);
        own_basis_error.push(
            setup
                .reduced_at_full_load(&own, &test.nodes)
                .map_or(f64::INFINITY, |d| ((d - newton) / newton).abs()),
        );
        let blended: f64 = order
            .iter()
            .zip(&weights)
            .map(|(&k, w)| w * lattice[k].newton.last().map_or(0.0, |&(_, d)| d))
            .sum();
        // the served law: blended ratios × this position's own linear force at its depth
        let served = AnmLattice {
            max_force: 0.0,
            positions: order.iter().map(|&k| lattice[k].served.clone()).collect(),
        };
        let mut zeta = vec![0.0; served.max_modes().max(test.served.probe.len())];
        let blend = served
            .stiffness_ratio(test.served.point, newton, params.neighbours, &mut zeta)
            .ratio;
        let (own_lambda, _) = test.served.load_at_depth(newton, &mut zeta);
        let exact = own_lambda * test.served.d_linear / newton;
        // seed 001 §5 online: PODI basis, interpolated tangent, load and f_p^nl, one series
        let (online_error, online_us) = online_at(
            &setup,
            &lattice,
            &stored,
            &order,
            &weights,
            &test,
            (&dofs, &stiffness),
            modes,
            &mut failures,
        )?;
        rows.push(TestRow {
            online_error,
            online_us,
            correction: ((1.0 - exact) / exact).abs(),
            served_error: ((blend - exact) / exact).abs(),
            response_error: ((blended - newton) / newton).abs(),
            centre: test.centre,
            nearest_m: distances[0],
            newton,
            error,
            projection,
            failures,
        });
    }
    Ok(LatticeStudy {
        lattice: lattice.iter().map(|p| p.centre).collect(),
        modes,
        rows,
        own_basis_error,
    })
}
