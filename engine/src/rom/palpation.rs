//! The large-deformation palpation model served online: ANM-POD load paths on a lattice of
//! surface positions (seed 001), turned into a nonlinear force–depth law under the tool.
//!
//! # Offline ([`AnmLattice::build`])
//! Lattice positions are accessible surface nodes chosen by farthest-point sampling. At each,
//! a force of `max_force` presses along the inward surface normal (spread over the nodes within
//! the probe's radius); full Newton–Raphson follows it in load steps, their states give a POD
//! basis, the reduced St Venant–Kirchhoff tensors are built on it and the ANM continuation at
//! order 6 follows the branch to the full load. A position keeps its path (the series of each
//! step: `O(r · order)` numbers), the reduced probe row (`d = probe·ζ` is the displacement under
//! the load along the normal) and its linear displacement under the full load, `d_lin`.
//!
//! # Online ([`AnmLattice::stiffness_ratio`])
//! For a contact at point `p` pressed to depth `δ`, each of the `k` nearest positions gives its
//! load factor `λ(δ)` by inverting `d(a) = δ` on its path (scan and bisection of the series,
//! `O(r · order)` per evaluation, independent of the mesh), hence the ratio of its nonlinear to
//! its linear force at that depth, `s = λ(δ) d_lin / δ` (`s → 1` as `δ → 0`). The ratios are
//! blended with inverse-distance weights. Past the end of a path the law continues along the
//! path's last tangent (finite, monotone) and the evaluation says so. The palpation effect
//! multiplies the linear vademecum's contact force `C(s)⁻¹δ` by this ratio: the direction and
//! the spatial variation come from the PGD vademecum, the stiffening or softening with depth
//! from the reduced large-deformation model.
//!
//! Interpolating the force–depth responses of neighbours rather than their bases is the
//! choice measured in [`super::lattice`]: for a load concentrated under a tool, interpolated
//! bases (PODI or Grassmann) miss the dimple under the tool at a new position by tens of per
//! cent, while the responses vary smoothly with position.

use super::anm::{self, AnmParams, Path, Series};
use super::pod::{Pod, PodCriterion};
use super::study::StudyError;
use super::svk::ReducedSvk;
use super::unit;
use crate::fem::OrganModel;
use crate::fem::hyperelastic::{LawMap, Volumetric};
use crate::fem::nonlinear_static::{self, NewtonParams};
use crate::mesh::boundary::triangle_area_normal;

/// Settings of the lattice build.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnmLatticeParams {
    /// Lattice positions.
    pub positions: usize,
    /// Force at the end of each path (N).
    pub max_force: f64,
    /// Radius of the loaded patch (m), the probe's.
    pub patch_radius: f64,
    /// Newton load steps (snapshots) per position.
    pub load_steps: usize,
    /// Most POD modes.
    pub modes: usize,
    /// Truncation order of the ANM series (1…8; seed 001 §3): a higher order covers a longer
    /// stretch of the path per step (fewer steps) at more numbers per step.
    pub order: usize,
}

impl Default for AnmLatticeParams {
    /// 16 positions, 2 N, 6 load steps, 9 modes, order 6 (seed 001).
    fn default() -> Self {
        Self {
            positions: 16,
            max_force: 2.0,
            patch_radius: 0.0,
            load_steps: 6,
            modes: 9,
            order: 6,
        }
    }
}

/// One lattice position.
#[derive(Debug, Clone, PartialEq)]
pub struct AnmPosition {
    /// The surface node.
    pub node: usize,
    /// Its reference position (m).
    pub point: [f64; 3],
    /// Unit inward normal: the direction of the load.
    pub normal: [f64; 3],
    /// The reduced probe row.
    pub probe: Vec<f64>,
    /// Linear displacement under the full load (m).
    pub d_linear: f64,
    /// The ANM path of the reduced model to the full load.
    pub path: Path,
}

/// The lattice of an organ.
#[derive(Debug, Clone, PartialEq)]
pub struct AnmLattice {
    /// Force at the end of every path (N).
    pub max_force: f64,
    /// The positions.
    pub positions: Vec<AnmPosition>,
}

/// What one online evaluation found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stiffening {
    /// Nonlinear over linear force at this depth (1 at zero depth).
    pub ratio: f64,
    /// Whether some neighbour's path ended before this depth (the law was extrapolated).
    pub extrapolated: bool,
    /// The distance from the point to the nearest lattice position (m).
    pub nearest_m: f64,
    /// The nearest positions (indices into [`AnmLattice::positions`], nearest first): the first
    /// `count` — those blended, and at least [`RATE_NEIGHBOURHOOD`], whose interpolation rates
    /// the error estimate takes.
    pub blended: [usize; 8],
    /// How many of `blended` are set.
    pub count: usize,
    /// The uncertainty of the ratio past the paths' ends: the largest over the neighbours
    /// blended whose path ended before this depth (0 within the paths) of
    /// `max(|s_i(δ) − s_i(d_end)|, |1 − s_i(d_end)| (δ − d_end) / d_end)`.
    pub beyond: f64,
}

/// The positions around a contact whose interpolation rates its error estimate takes (the
/// largest), however many it blends: one position's own rate is one leave-one-out draw, and a
/// contact at the reduced fidelity (the nearest position alone) is no better known than one
/// blending four.
pub const RATE_NEIGHBOURHOOD: usize = 4;

/// The relative error of a lattice position's own ANM-POD path against full Newton at the same
/// position: the floor of [`Stiffening::error`]. The lattice test holds the path's load factor
/// within 1e-3 of Newton's at every depth Newton reached (`engine/tests/it/large_palpation.rs`).
pub const PATH_RELATIVE_ERROR: f64 = 1e-3;

/// The margin on the leave-one-out's largest ratio ([`AnmLattice::interpolation_rates`]): the
/// left-out positions are a few draws (four depths at each of 9–16 positions), and a contact
/// can sit where the organ changes faster than between any two positions. Without it the
/// estimate bounded 95.2 % of the liver's sampled states within and past the paths, the
/// lowest ratio of estimate to true error being 0.50; with it, see `docs/accuracy.md`.
pub const LEAVE_ONE_OUT_MARGIN: f64 = 2.0;

impl Stiffening {
    /// The estimated error of [`Stiffening::ratio`] against the full-order model's ratio at this
    /// point and depth,
    ///
    /// `e = rate · |1 − s| · dist + beyond + PATH_RELATIVE_ERROR · s`,
    ///
    /// with `rate` the largest of the nearest positions' [`AnmLattice::interpolation_rates`]
    /// (1/m): the interpolated nonlinear correction `1 − s` is uncertain in proportion to the
    /// distance to the nearest position whose path was computed, and past the paths the
    /// correction may keep growing at the rate it grew along them ([`Stiffening::beyond`]).
    /// Without rates (a lattice of one position) the whole correction is uncertain off the
    /// position. Multiplied by the linear force, it bounds the served force's error;
    /// `vademecum study` measures how often.
    pub fn error(&self, rates: &[f64]) -> f64 {
        let correction = (1.0 - self.ratio).abs();
        let rate = self.blended[..self.count.min(8)]
            .iter()
            .filter_map(|&i| rates.get(i))
            .fold(None, |m: Option<f64>, &r| Some(m.map_or(r, |m| m.max(r))));
        let interpolation = match rate {
            Some(rate) => rate * self.nearest_m * correction,
            None if self.nearest_m > 0.0 => correction,
            None => 0.0,
        };
        interpolation + self.beyond + PATH_RELATIVE_ERROR * self.ratio.abs()
    }
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum()
}

impl AnmPosition {
    /// The load factor at which the displacement under the load reaches `depth`, and whether
    /// it was extrapolated past the path's end.
    pub fn load_at_depth(&self, depth: f64, zeta: &mut [f64]) -> (f64, bool) {
        if depth <= 0.0 {
            return (0.0, false);
        }
        let d = |s: &Series, a: f64, z: &mut [f64]| self.depth_and_load(s, a, z);
        for (s, &end) in self.path.steps.iter().zip(&self.path.ends) {
            let (d_end, _) = d(s, end, zeta);
            if depth <= d_end {
                // bisection on a ∈ [0, end] (the displacement grows along the branch)
                let (mut lo, mut hi) = (0.0, end);
                for _ in 0..52 {
                    let mid = 0.5 * (lo + hi);
                    if d(s, mid, zeta).0 < depth {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                return (d(s, 0.5 * (lo + hi), zeta).1, false);
            }
        }
        // past the end: continue along the last tangent
        let (Some(s), Some(&end)) = (self.path.steps.last(), self.path.ends.last()) else {
            return (0.0, true);
        };
        let h = 1e-6 * end.max(1e-12);
        let (d1, l1) = d(s, end, zeta);
        let (d0, l0) = d(s, end - h, zeta);
        let slope = if d1 > d0 {
            (l1 - l0) / (d1 - d0)
        } else {
            l1 / d1.max(f64::MIN_POSITIVE)
        };
        (l1 + slope.max(0.0) * (depth - d1), true)
    }

    /// The displacement under the load and the load factor at arc-length `a` of series `s`.
    fn depth_and_load(&self, s: &Series, a: f64, zeta: &mut [f64]) -> (f64, f64) {
        let l = s.eval(a, zeta);
        (self.probe.iter().zip(zeta.iter()).map(|(p, z)| p * z).sum(), l)
    }

    /// Where the path ends: the displacement under the load and the load factor there.
    pub fn path_end(&self, zeta: &mut [f64]) -> Option<(f64, f64)> {
        let (s, &end) = (self.path.steps.last()?, self.path.ends.last()?);
        Some(self.depth_and_load(s, end, zeta))
    }

    /// This position's nonlinear-to-linear force ratio at `depth` (`λ(δ) d_lin / δ`) and the
    /// uncertainty of its part past the path's end (0 within the path):
    /// `max(|s(δ) − s(d_end)|, |1 − s(d_end)| (δ − d_end) / d_end)` — the change the
    /// extrapolation makes, or the nonlinear correction growing past the path at the rate it
    /// grew along it (to first order the correction is proportional to the depth), whichever
    /// is larger.
    fn ratio_at(&self, depth: f64, zeta: &mut [f64]) -> (f64, f64, bool) {
        let (lambda, extrapolated) = self.load_at_depth(depth, zeta);
        let ratio = lambda * self.d_linear / depth;
        let beyond = match self.path_end(zeta).filter(|_| extrapolated) {
            Some((d_end, l_end)) if d_end > 0.0 => {
                let at_end = l_end * self.d_linear / d_end;
                (ratio - at_end).abs().max((1.0 - at_end).abs() * (depth - d_end).max(0.0) / d_end)
            }
            _ => 0.0,
        };
        (ratio, beyond, extrapolated)
    }
}

/// The fewest positions a lattice built for a target error tries
/// ([`AnmLattice::build_for_target`]); then twice as many, ….
pub const FEWEST_TARGET_POSITIONS: usize = 2;

/// What a target error chose of a lattice ([`AnmLattice::build_for_target`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LatticeTarget {
    /// The target: the largest relative error of the served force over the checked states.
    pub error: f64,
    /// Whether the lattice kept meets it (when none does, the most positions are kept).
    pub met: bool,
    /// The most positions tried.
    pub most: usize,
    /// Each size tried, fewest first: its positions and its largest relative error.
    pub tried: Vec<(usize, f64)>,
}

impl AnmLattice {
    /// Builds the lattice of `organ` (St Venant–Kirchhoff with `laws`) (see the
    /// [module docs](self)); `progress(done, total)` after each position.
    pub fn build(
        organ: &OrganModel,
        laws: &LawMap,
        params: &AnmLatticeParams,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<Self, StudyError> {
        let order = Self::order(organ, params)?;
        let mut positions = Vec::with_capacity(order.len());
        for (done, &(node, inward)) in order.iter().enumerate() {
            positions.push(Self::position_of(organ, laws, params, node, inward)?);
            progress(done + 1, order.len());
        }
        Ok(Self {
            max_force: params.max_force,
            positions,
        })
    }

    /// The fewest positions, in farthest-point order, that meet a target error: the lattice
    /// of [`FEWEST_TARGET_POSITIONS`] positions, then twice as many, … up to
    /// `params.positions` (each size the first positions of the next: nothing is built
    /// twice), each checked by `error_of` (the largest relative error of its served force over
    /// states the caller checks it at: [`super::lattice_check::lattice_error`]). The first
    /// size within `target` is kept; none within it, the most positions are kept and the
    /// target is not met. `progress(done, most)` after each position.
    pub fn build_for_target(
        organ: &OrganModel,
        laws: &LawMap,
        params: &AnmLatticeParams,
        target: f64,
        mut error_of: impl FnMut(&Self) -> f64,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<(Self, LatticeTarget), StudyError> {
        let order = Self::order(organ, params)?;
        let most = order.len();
        let mut lattice = Self {
            max_force: params.max_force,
            positions: Vec::with_capacity(most),
        };
        let mut tried = Vec::new();
        let mut n = FEWEST_TARGET_POSITIONS.min(most);
        loop {
            for &(node, inward) in &order[lattice.positions.len()..n] {
                lattice.positions.push(Self::position_of(organ, laws, params, node, inward)?);
                progress(lattice.positions.len(), most);
            }
            let e = error_of(&lattice);
            tried.push((n, e));
            if e <= target || n == most {
                let t = LatticeTarget {
                    error: target,
                    met: e <= target,
                    most,
                    tried,
                };
                return Ok((lattice, t));
            }
            n = (2 * n).min(most);
        }
    }

    /// The positions of a lattice of `organ`: up to `params.positions` accessible surface
    /// nodes in farthest-point order from the node nearest the accessible centroid (nested:
    /// the first `n` of a larger lattice are the lattice of `n`), each with its inward normal.
    pub fn order(organ: &OrganModel, params: &AnmLatticeParams) -> Result<Vec<(usize, [f64; 3])>, StudyError> {
        if params.positions == 0 || !(params.max_force.is_finite() && params.max_force > 0.0) || params.load_steps == 0 {
            return Err(StudyError::Unsupported(
                "the lattice needs at least one position, a positive force and a load step".into(),
            ));
        }
        let mesh = &organ.mesh;
        let normals = surface_normals(organ);
        let candidates = loadable_nodes(organ, &normals);
        if candidates.is_empty() {
            return Err(StudyError::Unsupported(
                "the organ has no accessible surface node free to move".into(),
            ));
        }
        // farthest-point sampling from the node nearest the accessible centroid
        let mut centroid = [0.0; 3];
        for &n in &candidates {
            for k in 0..3 {
                centroid[k] += mesh.nodes[n][k] / candidates.len() as f64;
            }
        }
        let first = *candidates
            .iter()
            .min_by(|&&a, &&b| dist2(mesh.nodes[a], centroid).total_cmp(&dist2(mesh.nodes[b], centroid)))
            .expect("not empty");
        let mut chosen = vec![first];
        let mut far: Vec<f64> = candidates.iter().map(|&n| dist2(mesh.nodes[n], mesh.nodes[first])).collect();
        while chosen.len() < params.positions.min(candidates.len()) {
            let (i, _) = far.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).expect("not empty");
            let next = candidates[i];
            chosen.push(next);
            for (f, &n) in far.iter_mut().zip(&candidates) {
                *f = f.min(dist2(mesh.nodes[n], mesh.nodes[next]));
            }
        }
        Ok(chosen
            .into_iter()
            .map(|node| (node, unit(normals[node]).expect("filtered").map(|x| -x)))
            .collect())
    }

    /// The position at `node` pressed along `inward` ([`Self::position`] on `organ`).
    fn position_of(
        organ: &OrganModel,
        laws: &LawMap,
        params: &AnmLatticeParams,
        node: usize,
        inward: [f64; 3],
    ) -> Result<AnmPosition, StudyError> {
        Self::position(&organ.mesh, laws, &organ.accessible_nodes, &organ.problem, params, node, inward)
    }

    /// One position: the load `max_force` along the unit `normal` at `node`, spread over the
    /// accessible nodes within the patch radius, on the supports of `base`.
    pub(crate) fn position(
        mesh: &crate::mesh::Mesh,
        laws: &LawMap,
        accessible: &[usize],
        base: &crate::fem::linear_static::StaticProblem,
        params: &AnmLatticeParams,
        node: usize,
        normal: [f64; 3],
    ) -> Result<AnmPosition, StudyError> {
        let (patch, problem) = patch_load(mesh, accessible, base, params, node, normal);
        let mut snaps = Vec::new();
        let mut reached = 0.0;
        let newton = NewtonParams {
            steps: params.load_steps,
            ..NewtonParams::default()
        };
        // where full Newton stops short of the force (St Venant–Kirchhoff collapses under a
        // concentrated push), the path ends where it stopped and deeper presses extrapolate
        match nonlinear_static::solve(mesh, laws, Volumetric::PointWise, &problem, &newton, |l, u| {
            reached = l;
            snaps.push(u.to_vec());
        }) {
            Ok(_) => {}
            Err(nonlinear_static::NonlinearError::NoConvergence { .. }) if snaps.len() >= 2 => {}
            Err(e) => return Err(e.into()),
        }
        let pod = Pod::from_snapshots(
            &snaps,
            PodCriterion {
                energy: 1.0 - 1e-12,
                max_modes: params.modes,
            },
        )?;
        let model = ReducedSvk::build(mesh, laws, &pod)?;
        let f = pod.project(&problem.forces);
        let probe: Vec<f64> = (0..pod.modes).map(|k| super::mean_along(pod.mode(k), &patch, normal)).collect();
        let anm = AnmParams {
            order: params.order,
            ..AnmParams::default()
        };
        let path = anm::continuation(&model, &f, reached, &anm)?;
        // linear displacement under the full load: the order-1 term at the origin
        let mut k = model.k1.clone();
        crate::dense::cholesky(&mut k, pod.modes).map_err(|pivot| anm::AnmError::Unstable { lambda: 0.0, pivot })?;
        let mut z = f.clone();
        crate::dense::cholesky_solve(&k, pod.modes, &mut z);
        let d_linear = probe.iter().zip(&z).map(|(p, z)| p * z).sum();
        Ok(AnmPosition {
            node,
            point: mesh.nodes[node],
            normal,
            probe,
            d_linear,
            path,
        })
    }

    /// The nonlinear-to-linear force ratio at `point` pressed to `depth` (m), blended over the
    /// `k` nearest positions by inverse squared distance; `zeta` is scratch of the largest
    /// reduced size (see [`AnmLattice::max_modes`]).
    pub fn stiffness_ratio(&self, point: [f64; 3], depth: f64, k: usize, zeta: &mut [f64]) -> Stiffening {
        self.blend(point, depth, k, None, zeta)
    }

    /// The depth (m) within which a contact at any of `points` is answered from the paths
    /// themselves: the shallowest end of the paths of the positions around those points (the
    /// [`RATE_NEIGHBOURHOOD`] nearest of each, those whose laws a contact there blends and
    /// whose rates its estimate takes). Deeper, some blended law is extrapolated past its path
    /// ([`Stiffening::extrapolated`]) and the answer's error estimate grows with the depth.
    /// `None` without positions or paths. Allocates: call it once, to plan a trajectory.
    pub fn reach_at(&self, points: &[[f64; 3]]) -> Option<f64> {
        let mut zeta = vec![0.0; self.max_modes()];
        let mut reach = f64::INFINITY;
        for &x in points {
            let st = self.stiffness_ratio(x, f64::MIN_POSITIVE, RATE_NEIGHBOURHOOD, &mut zeta);
            for &i in &st.blended[..st.count] {
                let p = &self.positions[i];
                if let Some((d, _)) = p.path_end(&mut zeta[..p.probe.len()]).filter(|&(d, _)| d > 0.0 && d.is_finite()) {
                    reach = reach.min(d);
                }
            }
        }
        reach.is_finite().then_some(reach)
    }

    /// [`AnmLattice::stiffness_ratio`] without position `skip` (the leave-one-out of
    /// [`AnmLattice::spread_factor`]).
    fn blend(&self, point: [f64; 3], depth: f64, k: usize, skip: Option<usize>, zeta: &mut [f64]) -> Stiffening {
        let usable = self.positions.len() - usize::from(skip.is_some_and(|s| s < self.positions.len()));
        if !(depth.is_finite() && depth > 0.0) || usable == 0 {
            return Stiffening {
                ratio: 1.0,
                extrapolated: false,
                nearest_m: 0.0,
                blended: [0; 8],
                count: 0,
                beyond: 0.0,
            };
        }
        // the k nearest, by insertion into a small fixed array (no allocation)
        let mut best = [(f64::INFINITY, usize::MAX); 8];
        let k = k.clamp(1, best.len()).min(usable);
        // the neighbourhood whose rates the error estimate takes: at least the four nearest,
        // whatever the blend
        let hood = k.max(RATE_NEIGHBOURHOOD.min(usable));
        for (i, p) in self.positions.iter().enumerate() {
            if Some(i) == skip {
                continue;
            }
            let d = dist2(p.point, point);
            if d < best[hood - 1].0 {
                let mut j = hood - 1;
                while j > 0 && best[j - 1].0 > d {
                    best[j] = best[j - 1];
                    j -= 1;
                }
                best[j] = (d, i);
            }
        }
        let nearest_m = best[0].0.sqrt();
        let blended = best.map(|(_, i)| i);
        let (mut num, mut den, mut extrapolated, mut beyond_max) = (0.0, 0.0, false, 0.0f64);
        for &(d2, i) in &best[..k] {
            let p = &self.positions[i];
            let r = p.probe.len();
            let (ratio, beyond, ex) = p.ratio_at(depth, &mut zeta[..r]);
            extrapolated |= ex;
            if d2 == 0.0 {
                return Stiffening {
                    ratio,
                    extrapolated: ex,
                    nearest_m,
                    blended,
                    count: hood,
                    beyond,
                };
            }
            beyond_max = beyond_max.max(beyond);
            num += ratio / d2;
            den += 1.0 / d2;
        }
        let ratio = num / den;
        Stiffening {
            ratio: if ratio.is_finite() && ratio > 0.0 { ratio } else { 1.0 },
            extrapolated,
            nearest_m,
            blended,
            count: hood,
            beyond: beyond_max,
        }
    }

    /// The rate (1/m), per position, at which the interpolated correction's uncertainty grows
    /// with the distance to the nearest position ([`Stiffening::error`]), calibrated on the
    /// lattice itself by leave-one-out: each position's own law, at a quarter, half, three
    /// quarters and the whole of its path's depth, is predicted from its `k` nearest other
    /// positions, and its rate is [`LEAVE_ONE_OUT_MARGIN`] times the largest
    /// `|predicted − own| / (|1 − predicted| · distance)` met (the distance to the nearest
    /// other position): how fast the organ's law changes around it. Empty for a lattice of
    /// fewer than two positions (nothing to leave out). Allocates: call it once, when a session
    /// starts.
    pub fn interpolation_rates(&self, k: usize) -> Vec<f64> {
        if self.positions.len() < 2 {
            return Vec::new();
        }
        let mut zeta = vec![0.0; self.max_modes()];
        self.positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let r = p.probe.len();
                let Some((d_end, _)) = p.path_end(&mut zeta[..r]).filter(|&(d, _)| d > 0.0 && d.is_finite()) else {
                    return 0.0;
                };
                let mut rate = 0.0f64;
                for q in 1..=4 {
                    let depth = d_end * q as f64 / 4.0;
                    let (own, _, _) = p.ratio_at(depth, &mut zeta[..r]);
                    let guess = self.blend(p.point, depth, k, Some(i), &mut zeta);
                    let scale = (1.0 - guess.ratio).abs().max(PATH_RELATIVE_ERROR) * guess.nearest_m;
                    let miss = (guess.ratio - own).abs() - PATH_RELATIVE_ERROR * own.abs();
                    if miss > 0.0 && scale > 0.0 && (miss / scale).is_finite() {
                        rate = rate.max(miss / scale);
                    }
                }
                LEAVE_ONE_OUT_MARGIN * rate
            })
            .collect()
    }

    /// The largest reduced size of the positions (the scratch `stiffness_ratio` needs).
    pub fn max_modes(&self) -> usize {
        self.positions.iter().map(|p| p.probe.len()).max().unwrap_or(0)
    }
}

/// Area-weighted outward vertex normals of `organ`'s boundary surface (zero off it).
pub fn surface_normals(organ: &OrganModel) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0; 3]; organ.mesh.n_nodes()];
    for t in organ.boundary.triangles() {
        let (area, n) = triangle_area_normal(&organ.mesh, t);
        for &v in &t {
            for k in 0..3 {
                normals[v][k] += area * n[k];
            }
        }
    }
    normals
}

/// The large-deformation law of `model` a lattice is built with: St Venant–Kirchhoff with each
/// material's E and ν (seed 001), whatever model the materials name.
pub fn svk_laws(model: &OrganModel) -> LawMap {
    LawMap {
        laws: model
            .materials
            .table
            .iter()
            .map(crate::material::hyperelastic::Hyperelastic::svk)
            .collect(),
        of_cell: model.materials.of_cell.clone(),
    }
}

/// The accessible nodes a lattice may load: with a surface normal, and free to move.
pub fn loadable_nodes(organ: &OrganModel, normals: &[[f64; 3]]) -> Vec<usize> {
    organ
        .accessible_nodes
        .iter()
        .copied()
        .filter(|&n| unit(normals[n]).is_some() && (0..3).all(|k| !organ.problem.constrained[3 * n + k]))
        .collect()
}

/// The load of a lattice position: `max_force` along the unit `normal` at `node`, spread over
/// the accessible nodes within the patch radius, on the supports of `base` (the patch, and
/// the problem).
fn patch_load(
    mesh: &crate::mesh::Mesh,
    accessible: &[usize],
    base: &crate::fem::linear_static::StaticProblem,
    params: &AnmLatticeParams,
    node: usize,
    normal: [f64; 3],
) -> (Vec<usize>, crate::fem::linear_static::StaticProblem) {
    let patch: Vec<usize> = accessible
        .iter()
        .copied()
        .filter(|&n| n == node || dist2(mesh.nodes[n], mesh.nodes[node]) <= params.patch_radius.powi(2))
        .collect();
    let mut problem = base.clone();
    problem.forces.fill(0.0);
    problem.prescribed.fill(0.0);
    crate::fem::loads::add_distributed_force(&mut problem.forces, &patch, normal.map(|x| x * params.max_force));
    (patch, problem)
}

/// The full-order force–depth law at one surface node: what a lattice position's path
/// approximates, computed by full Newton–Raphson on the mesh (the reference of the error
/// estimate's check in `vademecum study`).
#[derive(Debug, Clone, PartialEq)]
pub struct NewtonLaw {
    /// The surface node.
    pub node: usize,
    /// Its reference position (m).
    pub point: [f64; 3],
    /// The full model's linear displacement under the full load (m): its responses to loads
    /// a thousandth and two thousandths as large, extrapolated to zero load.
    pub d_linear: f64,
    /// `(λ, d)`: the load factor of each converged Newton step and the displacement under the
    /// load there (m).
    pub steps: Vec<(f64, f64)>,
}

impl NewtonLaw {
    /// Full Newton in `params.load_steps` steps at `node` (an accessible node with a surface
    /// normal), with the load of a lattice position there (`max_force` along the inward normal,
    /// over the patch). Where Newton stops short of the full load, the steps it converged.
    pub fn at(organ: &OrganModel, laws: &LawMap, params: &AnmLatticeParams, node: usize) -> Result<Self, StudyError> {
        let normals = surface_normals(organ);
        let Some(inward) = normals.get(node).and_then(|&n| unit(n)).map(|n| n.map(|x| -x)) else {
            return Err(StudyError::Unsupported(format!("node {node} has no surface normal")));
        };
        Self::along(organ, laws, params, node, inward)
    }

    /// [`NewtonLaw::at`] with the load along the unit vector `inward` (the organ's own surface
    /// normal need not be the one the load follows: on an organ cut through `node`, the normal
    /// of the uncut surface).
    pub fn along(organ: &OrganModel, laws: &LawMap, params: &AnmLatticeParams, node: usize, inward: [f64; 3]) -> Result<Self, StudyError> {
        let mesh = &organ.mesh;
        let (patch, problem) = patch_load(mesh, &organ.accessible_nodes, &organ.problem, params, node, inward);
        let mut steps = Vec::new();
        let newton = NewtonParams {
            steps: params.load_steps,
            ..NewtonParams::default()
        };
        match nonlinear_static::solve(mesh, laws, Volumetric::PointWise, &problem, &newton, |l, u| {
            // a step reported twice (the last, once converged) is one state
            if steps.last().is_none_or(|&(last, _)| last != l) {
                steps.push((l, super::mean_along(u, &patch, inward)));
            }
        }) {
            Ok(_) => {}
            Err(nonlinear_static::NonlinearError::NoConvergence { .. }) if !steps.is_empty() => {}
            Err(e) => return Err(e.into()),
        }
        // the linear response by Richardson extrapolation of two small loads: d(ε)/ε is
        // d_lin + O(ε), so 2 d(ε)/ε − d(2ε)/(2ε) is d_lin + O(ε²)
        const SMALL: f64 = 1e-3;
        let small = |scale: f64| -> Result<f64, StudyError> {
            let mut p = problem.clone();
            p.forces.iter_mut().for_each(|f| *f *= scale);
            let mut d = 0.0;
            let one = NewtonParams {
                steps: 1,
                ..NewtonParams::default()
            };
            nonlinear_static::solve(mesh, laws, Volumetric::PointWise, &p, &one, |_, u| {
                d = super::mean_along(u, &patch, inward)
            })?;
            Ok(d / scale)
        };
        let d_linear = 2.0 * small(SMALL)? - small(2.0 * SMALL)?;
        Ok(Self {
            node,
            point: mesh.nodes[node],
            d_linear,
            steps,
        })
    }

    /// `(λ, depth, ratio)` of every step: its load factor, and the full model's
    /// nonlinear-to-linear force ratio at the depth it reached, `λ d_lin / d` (what
    /// [`AnmLattice::stiffness_ratio`] serves).
    pub fn ratios(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        self.steps
            .iter()
            .filter(|&&(_, d)| d > 0.0)
            .map(|&(l, d)| (l, d, l * self.d_linear / d))
    }
}

/// The lattice as flat arrays (the bundle's `anm_*` arrays).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LatticeArrays {
    /// `[max_force]`.
    pub max_force: Vec<f64>,
    /// Surface node of each position.
    pub nodes: Vec<i64>,
    /// Points, `P × 3`.
    pub points: Vec<f64>,
    /// Inward normals, `P × 3`.
    pub normals: Vec<f64>,
    /// `d_lin` per position.
    pub d_linear: Vec<f64>,
    /// Reduced size per position.
    pub modes: Vec<i64>,
    /// Probe rows, concatenated.
    pub probe: Vec<f64>,
    /// Steps of position `p`: `step_ptr[p] .. step_ptr[p+1]`.
    pub step_ptr: Vec<i64>,
    /// Per step: order, scale, radius, end, λ⁰, end residual (`S × 6`).
    pub step_meta: Vec<f64>,
    /// Per step, concatenated: `ζ⁰` (r), `ζ_1..ζ_N` (N r), `λ_1..λ_N` (N).
    pub step_data: Vec<f64>,
}

impl AnmLattice {
    /// Flattens the lattice for a bundle.
    pub fn to_arrays(&self) -> LatticeArrays {
        let mut a = LatticeArrays {
            max_force: vec![self.max_force],
            step_ptr: vec![0],
            ..Default::default()
        };
        for p in &self.positions {
            a.nodes.push(p.node as i64);
            a.points.extend(p.point);
            a.normals.extend(p.normal);
            a.d_linear.push(p.d_linear);
            a.modes.push(p.probe.len() as i64);
            a.probe.extend(&p.probe);
            for ((s, &end), &res) in p.path.steps.iter().zip(&p.path.ends).zip(&p.path.residuals) {
                a.step_meta.extend([s.order as f64, s.scale, s.radius, end, s.lambda0, res]);
                a.step_data.extend(&s.zeta0);
                a.step_data.extend(&s.zeta);
                a.step_data.extend(&s.lambda);
            }
            a.step_ptr.push((a.step_meta.len() / 6) as i64);
        }
        a
    }

    /// Rebuilds a lattice from its arrays, checking every size and index (`n_nodes`: the
    /// mesh's node count).
    pub fn from_arrays(a: &LatticeArrays, n_nodes: usize) -> Result<Self, String> {
        let p = a.nodes.len();
        let ok = a.max_force.len() == 1
            && a.points.len() == 3 * p
            && a.normals.len() == 3 * p
            && a.d_linear.len() == p
            && a.modes.len() == p
            && a.step_ptr.len() == p + 1
            && a.step_meta.len().is_multiple_of(6)
            && a.step_ptr.first() == Some(&0)
            && a.step_ptr.last().is_some_and(|&s| s as usize == a.step_meta.len() / 6)
            && a.step_ptr.windows(2).all(|w| w[0] <= w[1])
            && a.modes.iter().all(|&r| r > 0 && r <= 64)
            && a.probe.len() == a.modes.iter().map(|&r| r as usize).sum::<usize>()
            && a.nodes.iter().all(|&n| n >= 0 && (n as usize) < n_nodes);
        if !ok {
            return Err("the large-deformation lattice arrays are inconsistent".into());
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(finite(&a.max_force)
            && finite(&a.points)
            && finite(&a.normals)
            && finite(&a.d_linear)
            && finite(&a.probe)
            && finite(&a.step_meta)
            && finite(&a.step_data))
        {
            return Err("the large-deformation lattice holds non-finite numbers".into());
        }
        let (mut probe_at, mut data_at) = (0, 0);
        let mut positions = Vec::with_capacity(p);
        for i in 0..p {
            let r = a.modes[i] as usize;
            let probe = a.probe[probe_at..probe_at + r].to_vec();
            probe_at += r;
            let mut path = Path {
                steps: Vec::new(),
                ends: Vec::new(),
                residuals: Vec::new(),
            };
            for s in a.step_ptr[i] as usize..a.step_ptr[i + 1] as usize {
                let m = &a.step_meta[6 * s..6 * s + 6];
                let order = m[0] as usize;
                if !(1..=anm::MAX_ORDER).contains(&order) || m[0].fract() != 0.0 {
                    return Err(format!("position {i}: series order {} out of range", m[0]));
                }
                let len = r + order * r + order;
                let data = a
                    .step_data
                    .get(data_at..data_at + len)
                    .ok_or("the lattice's series data is truncated")?;
                data_at += len;
                path.steps.push(Series {
                    r,
                    order,
                    zeta0: data[..r].to_vec(),
                    lambda0: m[4],
                    zeta: data[r..r + order * r].to_vec(),
                    lambda: data[r + order * r..].to_vec(),
                    scale: m[1],
                    radius: m[2],
                });
                path.ends.push(m[3]);
                path.residuals.push(m[5]);
            }
            positions.push(AnmPosition {
                node: a.nodes[i] as usize,
                point: [a.points[3 * i], a.points[3 * i + 1], a.points[3 * i + 2]],
                normal: [a.normals[3 * i], a.normals[3 * i + 1], a.normals[3 * i + 2]],
                probe,
                d_linear: a.d_linear[i],
                path,
            });
        }
        if data_at != a.step_data.len() {
            return Err("the lattice's series data has trailing values".into());
        }
        Ok(Self {
            max_force: a.max_force[0],
            positions,
        })
    }
}
