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
use crate::fem::hyperelastic::{LawMap, Volumetric};
use crate::fem::nonlinear_static::{self, NewtonParams};
use crate::mesh::boundary::triangle_area_normal;
use crate::scene::OrganModel;

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
}

impl Default for AnmLatticeParams {
    /// 16 positions, 2 N, 6 load steps, 9 modes (seed 001).
    fn default() -> Self {
        Self {
            positions: 16,
            max_force: 2.0,
            patch_radius: 0.0,
            load_steps: 6,
            modes: 9,
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
        let d = |s: &Series, a: f64, z: &mut [f64]| -> (f64, f64) {
            let l = s.eval(a, z);
            (self.probe.iter().zip(z.iter()).map(|(p, z)| p * z).sum(), l)
        };
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
        if params.positions == 0 || !(params.max_force.is_finite() && params.max_force > 0.0) || params.load_steps == 0 {
            return Err(StudyError::Unsupported(
                "the lattice needs at least one position, a positive force and a load step".into(),
            ));
        }
        let mesh = &organ.mesh;
        // area-weighted outward vertex normals of the boundary surface
        let mut normals = vec![[0.0; 3]; mesh.n_nodes()];
        for t in organ.boundary.triangles() {
            let (area, n) = triangle_area_normal(mesh, t);
            for &v in &t {
                for k in 0..3 {
                    normals[v][k] += area * n[k];
                }
            }
        }
        let candidates: Vec<usize> = organ
            .accessible_nodes
            .iter()
            .copied()
            .filter(|&n| unit(normals[n]).is_some() && (0..3).all(|k| !organ.problem.constrained[3 * n + k]))
            .collect();
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
        let mut positions = Vec::with_capacity(chosen.len());
        for (done, &node) in chosen.iter().enumerate() {
            let inward = unit(normals[node]).expect("filtered").map(|x| -x);
            positions.push(Self::position(
                mesh,
                laws,
                &organ.accessible_nodes,
                &organ.problem,
                params,
                node,
                inward,
            )?);
            progress(done + 1, chosen.len());
        }
        Ok(Self {
            max_force: params.max_force,
            positions,
        })
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
        let patch: Vec<usize> = accessible
            .iter()
            .copied()
            .filter(|&n| n == node || dist2(mesh.nodes[n], mesh.nodes[node]) <= params.patch_radius.powi(2))
            .collect();
        let mut problem = base.clone();
        problem.forces.fill(0.0);
        problem.prescribed.fill(0.0);
        crate::fem::loads::add_distributed_force(&mut problem.forces, &patch, normal.map(|x| x * params.max_force));
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
        let path = anm::continuation(&model, &f, reached, &AnmParams::default())?;
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
        if !(depth.is_finite() && depth > 0.0) || self.positions.is_empty() {
            return Stiffening {
                ratio: 1.0,
                extrapolated: false,
            };
        }
        // the k nearest, by insertion into a small fixed array (no allocation)
        let mut best = [(f64::INFINITY, usize::MAX); 8];
        let k = k.clamp(1, best.len()).min(self.positions.len());
        for (i, p) in self.positions.iter().enumerate() {
            let d = dist2(p.point, point);
            if d < best[k - 1].0 {
                let mut j = k - 1;
                while j > 0 && best[j - 1].0 > d {
                    best[j] = best[j - 1];
                    j -= 1;
                }
                best[j] = (d, i);
            }
        }
        let (mut num, mut den, mut extrapolated) = (0.0, 0.0, false);
        for &(d2, i) in &best[..k] {
            let p = &self.positions[i];
            let r = p.probe.len();
            let (lambda, ex) = p.load_at_depth(depth, &mut zeta[..r]);
            extrapolated |= ex;
            let ratio = lambda * p.d_linear / depth;
            if d2 == 0.0 {
                return Stiffening { ratio, extrapolated: ex };
            }
            num += ratio / d2;
            den += 1.0 / d2;
        }
        let ratio = num / den;
        Stiffening {
            ratio: if ratio.is_finite() && ratio > 0.0 { ratio } else { 1.0 },
            extrapolated,
        }
    }

    /// The largest reduced size of the positions (the scratch `stiffness_ratio` needs).
    pub fn max_modes(&self) -> usize {
        self.positions.iter().map(|p| p.probe.len()).max().unwrap_or(0)
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
