//! How well the per-answer error estimate ([`crate::pipeline::TickState::force_error_n`]) bounds the true
//! error: sampled contact states served as a session serves them, each beside the full-order
//! model's answer for the same state (what `vademecum study` reports and `cargo test` checks).
//!
//! - **Linear palpation**: at random points of the accessible surface, the force for a 1 mm
//!   press along the surface normal from the vademecum (`C(s)⁻¹δ`, exact local compliances)
//!   against the full model's: the stiffness factored, the unit loads `Σ_b w_b` over the
//!   triangle's patches solved, the response read back with the same patch weights.
//! - **Large deformations**: at surface nodes off the lattice, full Newton with a lattice
//!   position's load taken 1.5 times past the lattice's force ([`NewtonLaw`]): at each depth
//!   Newton reached, the served ratio against the full model's, the part past the lattice's
//!   paths included (where the estimate must cover the extrapolation).
//! - **Tearing**: the grasp pulled from virgin tissue in directions that mix the load and the
//!   two across it ([`TEAR_MIXES`]; the calibration pulls along each alone), at each step of
//!   the schedule the force the reduced model renders for its grasp displacement against the
//!   full-order model's for the same displacement ([`crate::damage::build::force_errors`]);
//!   and a second grasp of tissue a first pull along the load damaged to half the schedule,
//!   released ([`SECOND_GRASP`], [`crate::damage::build::force_errors_after`]), pulled along
//!   the load again and in the same mixed directions; a third grasp, after that first pull
//!   and a second one in the first mixed direction ([`THIRD_GRASP`]); a grasp of tissue
//!   another site's pull damaged ([`OTHER_SITE`]); and a grasp after a long sequence of pulls
//!   alternating between the two sites in every direction ([`MANY_PULLS`]) — none of which
//!   the build calibrates.
//! - **Cutting**: the scene's cut made in the session's own reduced model
//!   ([`crate::pipeline::session_cut_model`]), pressed at random points of the surface triangles that
//!   touch a cracked node along each axis, against the full XFEM's compliance there
//!   ([`crate::xfem::accuracy::patch_samples`]) — points between the cracked nodes the bare
//!   enrichment's calibration used ([`CUT`], [`CUT_BARE`]).
//! - **An organ cut and deformed largely** ([`LARGE_CUT`]): the scene's cut on the organ that
//!   deforms largely, pressed at surface nodes beside it with a lattice position's load,
//!   against Newton on the organ cut by split nodes ([`super::large_cut`]).
//! - **Co-rotational cutting** (seed 003): a tool pressing a surface triangle of the organ
//!   with a force ramped in over two seconds of frames and held, the co-rotational deformation
//!   stepped frame by frame as a session's frame thread steps it and each frame's ticks served
//!   as the cutting effect serves them (the latest correction blended in), against the
//!   co-rotational model's compliance at the deformation shown — a fresh factor of its warped
//!   stiffness at each frame's state ([`corotational_samples`]); on the uncut organ
//!   ([`COROTATIONAL`]) and on the organ cut by the scene's cut, pressed next to it
//!   ([`COROTATIONAL_CUT`]).

use crate::bundle::LoadedBundle;
use crate::fem::OrganModel;
use crate::offline::{self, BuildError};
use crate::pgd::Vademecum;
use crate::pipeline::palpation::LINEAR_RELATIVE_ERROR;
use crate::rng::Rng;
use crate::rom::lattice_check::{NEIGHBOURS, is_within_force, newton_laws};
use crate::rom::palpation::{AnmLattice, AnmLatticeParams, NewtonLaw};
use crate::rom::study::StudyError;

/// The pull directions the tearing samples take (multipliers of the patterns along the load
/// and the two across it, normalised): none is one the calibration pulls
/// ([`crate::damage::build::force_error_table`]: the axes and the four diagonals), each lies
/// between them, in both senses across.
pub const TEAR_MIXES: [[f64; 3]; 6] = [
    [1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [1.0, 2.0, 1.0],
    [2.0, 1.0, -1.0],
];

/// The tearing samples of the grasp site `off` (module docs): one per pull of [`TEAR_MIXES`]
/// and step of its schedule within the calibrated load levels, from virgin tissue (model
/// `"tearing"`); then, each time along the load and each of [`TEAR_MIXES`], later grasps of
/// damaged tissue, released in between, every earlier pull to half its site's schedule: a
/// second grasp ([`SECOND_GRASP`]) after a pull along the load; a third ([`THIRD_GRASP`])
/// after that pull and one in the first of [`TEAR_MIXES`]; and, when `other` (another grasp
/// site of the same tissue) is given, a grasp after that site's pull along its own load
/// ([`OTHER_SITE`]); and a grasp after [`MANY_PULLS_BEFORE`] pulls ([`MANY_PULLS`]):
/// alternately at this site and the other (this one alone without `other`), along the load
/// then in the first of [`TEAR_MIXES`] in turn. `done(k, n)` after each pull. Empty when the
/// site follows the pull along its load only (nothing mixes).
pub fn tear_samples(
    off: &std::sync::Arc<crate::damage::online::TearOffline>,
    other: Option<&std::sync::Arc<crate::damage::online::TearOffline>>,
    mut done: impl FnMut(usize, usize),
) -> Result<Vec<Sample>, crate::damage::reference::RunError> {
    use crate::damage::build::Prior;
    if off.patterns() != 3 || off.force_error.is_empty() {
        return Ok(Vec::new());
    }
    let Some((_, centre, r)) = off.model.grasp() else {
        return Ok(Vec::new());
    };
    let resultant = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    let unit = |mix: [f64; 3]| {
        let size = mix.iter().map(|m| m * m).sum::<f64>().sqrt();
        mix.map(|m| m / size)
    };
    let half = |site: &std::sync::Arc<crate::damage::online::TearOffline>| crate::damage::build::second_grasp_steps(&site.model);
    let second = vec![Prior::along(off, half(off))];
    let third = vec![
        Prior::along(off, half(off)),
        Prior {
            site: off.clone(),
            mix: unit(TEAR_MIXES[0]),
            steps: half(off),
        },
    ];
    let mut befores: Vec<(&'static str, Vec<Prior>)> = vec![(SECOND_GRASP, second), (THIRD_GRASP, third)];
    let other = other.filter(|o| o.model.load != off.model.load);
    if let Some(o) = other {
        befores.push((OTHER_SITE, vec![Prior::along(o, half(o))]));
    }
    // many pulls: the sites in turn, along their loads first, then across
    let many = (0..MANY_PULLS_BEFORE)
        .map(|k| {
            let site = match other {
                Some(o) if k % 2 == 1 => o,
                _ => off,
            };
            let round = if other.is_some() { k / 2 } else { k };
            match round {
                0 => Prior::along(site, half(site)),
                r => Prior {
                    site: site.clone(),
                    mix: unit(TEAR_MIXES[(r - 1) % TEAR_MIXES.len()]),
                    steps: half(site),
                },
            }
        })
        .collect();
    befores.push((MANY_PULLS, many));
    let later = std::iter::once([1.0, 0.0, 0.0]).chain(TEAR_MIXES);
    let pulls: Vec<(&'static str, &[Prior], [f64; 3])> = TEAR_MIXES
        .iter()
        .map(|&m| ("tearing", &[][..], m))
        .chain(
            befores
                .iter()
                .flat_map(|(model, b)| later.clone().map(move |m| (*model, &b[..], m))),
        )
        .collect();
    let mut out = Vec::new();
    for (k, &(model, before, mix)) in pulls.iter().enumerate() {
        let unit = unit(mix);
        let held = crate::damage::build::later_grasp(off, before);
        for [level, full, _] in crate::damage::build::force_errors_after(off, before, unit, None)? {
            let Some(e) = held.force_error_for(unit.map(|m| m * level)) else {
                continue;
            };
            let served = resultant * level;
            out.push(Sample {
                model,
                point_m: centre,
                depth_m: 0.0,
                beyond_range: false,
                within_force: true,
                served,
                truth: resultant * full,
                error: resultant * (level - full).abs(),
                estimate: served * e,
            });
        }
        done(k + 1, pulls.len());
    }
    Ok(out)
}

/// The model label of the tearing samples of a second grasp, of tissue a first pull along the
/// load damaged ([`tear_samples`]).
pub const SECOND_GRASP: &str = "tearing (second grasp)";

/// The model label of the tearing samples of a third grasp, of tissue two earlier pulls
/// damaged: along the load, then in the first of [`TEAR_MIXES`] ([`tear_samples`]).
pub const THIRD_GRASP: &str = "tearing (third grasp)";

/// The model label of the tearing samples of a grasp of tissue another grasp site's pull
/// damaged ([`tear_samples`]).
pub const OTHER_SITE: &str = "tearing (after another site)";

/// The model label of the cutting samples with the seed's local fields ([`cut_samples`]).
pub const CUT: &str = "cutting";

/// The model label of the cutting samples with the bare enrichment ([`cut_samples`]).
pub const CUT_BARE: &str = "cutting (bare enrichment)";

/// The model label of the cutting samples with the bare enrichment on the cut halfway
/// ([`cut_samples`]).
pub const CUT_BARE_HALFWAY: &str = "cutting (bare enrichment on the cut halfway)";

/// The model label of the co-rotational samples of an uncut organ ([`corotational_samples`]).
pub const COROTATIONAL: &str = "cutting (co-rotational correction)";

/// The model label of the co-rotational samples of a cut organ ([`corotational_samples`]).
pub const COROTATIONAL_CUT: &str = "cutting (co-rotational correction on the cut organ)";

/// The model label of the tearing samples of a grasp after a long sequence of pulls at two
/// sites ([`tear_samples`]).
pub const MANY_PULLS: &str = "tearing (after many pulls)";

/// The pulls before a [`MANY_PULLS`] grasp.
pub const MANY_PULLS_BEFORE: usize = 6;

/// The model label of the samples of an organ cut and deformed largely at once
/// ([`super::large_cut`]).
pub const LARGE_CUT: &str = "large deformations (on the cut organ)";

/// Every model label of the samples, in the order reports list them (none holds a comma: they
/// are CSV fields).
pub const MODELS: [&str; 13] = [
    "linear",
    "large",
    "tearing",
    SECOND_GRASP,
    THIRD_GRASP,
    OTHER_SITE,
    MANY_PULLS,
    CUT,
    CUT_BARE,
    CUT_BARE_HALFWAY,
    COROTATIONAL,
    COROTATIONAL_CUT,
    LARGE_CUT,
];

/// Frames over which [`corotational_samples`] ramps the tool's force in (two seconds at
/// 30 Hz), then holds it as long.
pub const RAMP: u32 = 60;

/// The co-rotational samples (module docs) of an organ (`mesh`, `materials`, `problem` with
/// the scene's loads, as a session's deformation takes them), cut by `cut` if given (the
/// deformation takes it before the first frame), pressed at `contact` (its
/// tissue force the full one, ramped in over [`RAMP`] frames then held as long): one sample
/// per tick, [`crate::pipeline::corotational::BLEND_TICKS`] ticks a frame, each the force served under
/// the blended correction for the imposed displacement under which the deformation's own
/// compliance gives the contact's force, beside that force, with the session's estimate
/// ([`crate::pipeline::corotational::corrected_force_error`]; the linear part's round-off added). The
/// served compliance is the rest compliance plus the correction, as the cutting effect's is
/// the vademecum's exact one plus the cut's plus the correction.
pub fn corotational_samples(
    mesh: &crate::mesh::Mesh,
    materials: &crate::fem::assembly::MaterialMap,
    problem: &crate::fem::linear_static::StaticProblem,
    contact: &crate::pipeline::Contact,
    cut: Option<&std::sync::Arc<crate::xfem::Enrichment>>,
) -> Result<Vec<Sample>, String> {
    use crate::pipeline::corotational::{BLEND_TICKS, Blend, CorotationalDeformation, contact_compliance, corrected_force_error};
    let (mut def, mut out) =
        CorotationalDeformation::new(0, mesh.clone(), materials.clone(), problem.clone(), None).map_err(|e| e.to_string())?;
    let uncut;
    let enr = match cut {
        Some(e) => {
            // the deformation takes the cut as a session's first frame after it landed would
            if def.step(Some((1, e)), None).map_err(|e| e.to_string())?.refused_cut {
                return Err(def.failure().unwrap_or("the co-rotational model refused the cut").to_string());
            }
            &**e
        }
        None => {
            uncut = crate::xfem::Enrichment::from_cut_cells(mesh, &[], &crate::xfem::XfemParams::default()).map_err(|e| e.to_string())?;
            &uncut
        }
    };
    let model = crate::xfem::corotational::CorotationalXfem::new(mesh, materials, problem, enr).map_err(|e| e.to_string())?;
    let rest = model.factor_at(&vec![0.0; model.n_dofs()], None).map_err(|e| e.to_string())?;
    let c0 = contact_compliance(&model, &rest, contact);
    let add = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| -> [[f64; 3]; 3] { std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] + b[i][j])) };
    let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    let point_m: [f64; 3] = std::array::from_fn(|i| (0..3).map(|v| contact.weights[v] * mesh.nodes[contact.nodes[v]][i]).sum());
    let mut blend = Blend::default();
    let mut out_samples = Vec::new();
    for frame in 1..=2 * RAMP {
        let mut c = *contact;
        c.tissue_force_n = contact.tissue_force_n.map(|x| x * (f64::from(frame) / f64::from(RAMP)).min(1.0));
        def.step(None, Some(&c)).map_err(|e| e.to_string())?;
        let truth = contact_compliance(&model, &model.factor_at(def.d(), None).map_err(|e| e.to_string())?, &c);
        let delta: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| truth[i][j] * c.tissue_force_n[j]).sum());
        let force = |dc: [[f64; 3]; 3]| crate::pgd::Vademecum::contact_force(&add(c0, dc), delta);
        for _ in 0..BLEND_TICKS {
            blend.land(*out.read(), Some(&c.nodes));
            let Some(now) = blend.delta(&c.nodes, blend.ticks()) else {
                continue;
            };
            let f = force(now);
            let Some(e) = corrected_force_error(f, blend.target(), |d| Some(force(d))) else {
                continue;
            };
            out_samples.push(Sample {
                model: if cut.is_some() { COROTATIONAL_CUT } else { COROTATIONAL },
                point_m,
                depth_m: 0.0,
                beyond_range: false,
                within_force: true,
                served: norm(f),
                truth: norm(c.tissue_force_n),
                error: norm(std::array::from_fn(|k| f[k] - c.tissue_force_n[k])),
                estimate: e + LINEAR_RELATIVE_ERROR * norm(f),
            });
        }
    }
    Ok(out_samples)
}

/// `count` contact points on organ 0 of a cutting `scene` cut by its planned cut (module
/// docs), each pressed along the three axes; with the bare enrichment, as many again on the
/// cut halfway (its first half of cells: the cut as a stroke leaves it midway, which the
/// calibration did not see; [`CUT_BARE_HALFWAY`]). `progress(done, total)` after each point.
/// The estimate is the session's ([`crate::pipeline::cutting::force_error`]); a bare-enrichment bundle
/// without the calibration gives none, and no samples.
pub fn cut_samples(
    scene: &crate::scene::Scene,
    model: &OrganModel,
    bundle: &LoadedBundle,
    count: usize,
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<Sample>, String> {
    use crate::xfem::reduced::Discontinuous;
    let disc = scene.spec.fidelity.xfem.discontinuous;
    let params = crate::pipeline::cut_params(scene, bundle.cut_sliver().map_err(|e| e.to_string())?);
    let organ_cuts = scene.planned_cuts().map_err(|e| e.to_string())?;
    let cells = crate::xfem::accuracy::cut_cells(&organ_cuts, model, &params).map_err(|e| e.to_string())?;
    let mut cuts = vec![(&cells[..], if disc == Discontinuous::Bare { CUT_BARE } else { CUT })];
    if disc == Discontinuous::Bare && cells.len() >= 2 {
        cuts.push((&cells[..cells.len() / 2], CUT_BARE_HALFWAY));
    }
    let bare = bundle.cut_bare_force_error().map_err(|e| e.to_string())?;
    let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    let total = cuts.len() * count;
    let mut out = Vec::new();
    for (k, &(cells, label)) in cuts.iter().enumerate() {
        let (mut reduced, _) = crate::pipeline::session_cut_model(scene, model, bundle).map_err(|e| e.to_string())?;
        reduced.cut(&model.mesh, cells).map_err(|e| e.to_string())?;
        let samples = crate::xfem::accuracy::patch_samples(model, &params, cells, &mut reduced.view(), count, |done, _| {
            progress(k * count + done, total)
        })
        .map_err(|e| e.to_string())?;
        out.extend(samples.into_iter().filter_map(|p| {
            let estimate = crate::pipeline::cutting::force_error(disc, bare, p.served)?;
            Some(Sample {
                model: label,
                point_m: p.point_m,
                depth_m: 0.0,
                beyond_range: false,
                within_force: true,
                served: norm(p.served),
                truth: norm(p.truth),
                error: norm(std::array::from_fn(|k| p.served[k] - p.truth[k])),
                estimate,
            })
        }));
    }
    Ok(out)
}

/// One sampled state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Sample {
    /// `"linear"` or `"large"`.
    pub model: &'static str,
    /// The surface point loaded (m).
    pub point_m: [f64; 3],
    /// The press's depth (m).
    pub depth_m: f64,
    /// Whether the served law was extrapolated past the paths of a lattice position it blends
    /// (large only).
    pub beyond_range: bool,
    /// Whether the state's force is within the lattice's (`max_force`; large only: the full
    /// model is pushed [`PAST_THE_LATTICE`](crate::rom::lattice_check::PAST_THE_LATTICE) times past it). Linear: always.
    pub within_force: bool,
    /// The served value: the force magnitude (N, linear) or the nonlinear-to-linear ratio
    /// (large; the force is the ratio times the exact linear force, so relative errors agree).
    pub served: f64,
    /// The full-order model's value, in the same unit.
    pub truth: f64,
    /// The true error, `|served − truth|` (the force difference's norm for linear).
    pub error: f64,
    /// The estimate the session attaches, in the same unit.
    pub estimate: f64,
}

impl Sample {
    /// Whether the estimate bounds the true error.
    pub fn bounded(&self) -> bool {
        self.error <= self.estimate
    }
}

/// What the samples say of the estimate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Coverage {
    /// States sampled.
    pub samples: usize,
    /// States whose estimate bounds their true error.
    pub bounded: usize,
    /// The median of estimate / true error over states with a nonzero error (how loose the
    /// bound is; `NaN` if none).
    pub median_ratio: f64,
    /// The largest true error relative to the truth.
    pub max_relative_error: f64,
}

impl Coverage {
    /// Sums up `samples`.
    pub fn of(samples: &[Sample]) -> Self {
        let mut ratios: Vec<f64> = samples.iter().filter(|s| s.error > 0.0).map(|s| s.estimate / s.error).collect();
        ratios.sort_by(f64::total_cmp);
        Self {
            samples: samples.len(),
            bounded: samples.iter().filter(|s| s.bounded()).count(),
            median_ratio: ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN),
            max_relative_error: samples
                .iter()
                .map(|s| s.error / s.truth.abs().max(f64::MIN_POSITIVE))
                .fold(0.0, f64::max),
        }
    }

    /// The share of states bounded (1 with no sample).
    pub fn fraction(&self) -> f64 {
        if self.samples == 0 {
            1.0
        } else {
            self.bounded as f64 / self.samples as f64
        }
    }
}

/// `count` linear-palpation states of organ `model` (whose bundle is `bundle`): see the
/// [module docs](self). Factors the organ's stiffness (seconds on a large organ).
pub fn linear_samples(model: &OrganModel, bundle: &LoadedBundle, count: usize) -> Result<Vec<Sample>, BuildError> {
    let v = &bundle.vademecum;
    let tris: Vec<[usize; 3]> = bundle
        .surface
        .iter()
        .copied()
        .filter(|t| t.iter().all(|&n| v.is_loadable(n)))
        .collect();
    if tris.is_empty() || count == 0 {
        return Ok(Vec::new());
    }
    let (dofs, _, chol, _, _) = offline::stiffness(model, &mut |_| {})?;
    let index: std::collections::HashMap<usize, usize> = v.load_nodes().iter().enumerate().map(|(j, &n)| (n, j)).collect();
    let patches = v.patches();
    let n = model.mesh.n_nodes();
    let nf = dofs.n_free();
    let mut rng = Rng(0x0E57_1A7E_5EED);
    let mut out = Vec::with_capacity(count);
    let zero = vec![0.0; 3 * n];
    while out.len() < count {
        let tri = tris[(rng.next_u64() % tris.len() as u64) as usize];
        let (a, b) = (rng.unit(), rng.unit());
        let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
        let w = [1.0 - a - b, a, b];
        let Some(served_c) = v.contact_compliance(tri, w, crate::pgd::Footprint::Tip) else {
            continue;
        };
        // the full model's contact law at s: each node's own compliance (unit forces over its
        // patch, read back over it), inverted, interpolated with the weights, inverted back
        let mut stiffness = nalgebra::Matrix3::<f64>::zeros();
        for (&node, &wa) in tri.iter().zip(&w) {
            if wa == 0.0 {
                continue;
            }
            let (nodes, pw) = &patches[index[&node]];
            let mut rhs = vec![0.0; 3 * nf];
            for d in 0..3 {
                let mut f = vec![0.0; 3 * n];
                for (&p, &x) in nodes.iter().zip(pw) {
                    f[3 * p + d] += x;
                }
                dofs.restrict(&f, &mut rhs[d * nf..(d + 1) * nf]);
            }
            chol.solve_many_in_place(&mut rhs, 3);
            let mut c = nalgebra::Matrix3::<f64>::zeros();
            let mut u = vec![0.0; 3 * n];
            for d in 0..3 {
                dofs.expand(&rhs[d * nf..(d + 1) * nf], &zero, &mut u);
                for (&p, &x) in nodes.iter().zip(pw) {
                    for i in 0..3 {
                        c[(i, d)] += x * u[3 * p + i];
                    }
                }
            }
            let Some(k) = c.try_inverse() else { continue };
            stiffness += wa * k;
        }
        let Some(true_c) = stiffness.try_inverse() else { continue };
        let true_c: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|d| true_c[(i, d)]));
        let normal = unit_normal(&bundle.nodes, tri);
        let depth = 1e-3;
        let delta = normal.map(|x| -depth * x);
        let served = Vademecum::contact_force(&served_c, delta);
        let truth = Vademecum::contact_force(&true_c, delta);
        let norm = |f: [f64; 3]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
        let point_m = std::array::from_fn(|k| (0..3).map(|i| w[i] * bundle.nodes[tri[i]][k]).sum());
        out.push(Sample {
            model: "linear",
            point_m,
            depth_m: depth,
            beyond_range: false,
            within_force: true,
            served: norm(served),
            truth: norm(truth),
            error: norm([0, 1, 2].map(|k| served[k] - truth[k])),
            estimate: LINEAR_RELATIVE_ERROR * norm(served),
        });
    }
    Ok(out)
}

/// The outward unit normal of triangle `t`.
fn unit_normal(nodes: &[[f64; 3]], t: [usize; 3]) -> [f64; 3] {
    let (p, q, r) = (nodes[t[0]], nodes[t[1]], nodes[t[2]]);
    let e1 = [0, 1, 2].map(|k| q[k] - p[k]);
    let e2 = [0, 1, 2].map(|k| r[k] - p[k]);
    let c = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let l = c.iter().map(|x| x * x).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
    c.map(|x| x / l)
}

/// The sorted relative errors of the served force of the states of `samples` within the
/// lattice's force.
pub fn within_force(samples: &[Sample]) -> Vec<f64> {
    let mut within: Vec<f64> = samples
        .iter()
        .filter(|s| s.within_force)
        .map(|s| s.error / s.truth.abs().max(f64::MIN_POSITIVE))
        .collect();
    within.sort_by(f64::total_cmp);
    within
}

/// Large-deformation states at `nodes` surface nodes of organ `model` off `lattice` (drawn at
/// random among the loadable nodes that are not lattice positions), with the lattice's build
/// settings `params`: see the [module docs](self). `progress(done, total)` after each node.
/// Nodes where Newton converges no step are skipped.
pub fn large_samples(
    model: &OrganModel,
    lattice: &AnmLattice,
    params: &AnmLatticeParams,
    nodes: usize,
    progress: impl FnMut(usize, usize),
) -> Result<Vec<Sample>, StudyError> {
    let exclude: Vec<usize> = lattice.positions.iter().map(|p| p.node).collect();
    let laws = newton_laws(
        model,
        &AnmLatticeParams {
            max_force: lattice.max_force,
            ..*params
        },
        &exclude,
        nodes,
        progress,
    )?;
    Ok(served(lattice, &laws, NEIGHBOURS))
}

/// Every state of `laws` served by `lattice` blending its `k` nearest positions, with the error
/// estimate a session attaches (the lattice's own leave-one-out rates for `k`).
pub fn served(lattice: &AnmLattice, laws: &[NewtonLaw], k: usize) -> Vec<Sample> {
    let rates = lattice.interpolation_rates(k);
    let mut zeta = vec![0.0; lattice.max_modes()];
    let mut out = Vec::new();
    for law in laws {
        for (lambda, depth, truth) in law.ratios() {
            let s = lattice.stiffness_ratio(law.point, depth, k, &mut zeta);
            out.push(Sample {
                model: "large",
                point_m: law.point,
                depth_m: depth,
                beyond_range: s.extrapolated,
                within_force: is_within_force(lambda),
                served: s.ratio,
                truth,
                error: (s.ratio - truth).abs(),
                estimate: s.error(&rates),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_model_labels_are_plain_csv_fields() {
        assert!(super::MODELS.iter().all(|m| !m.contains([',', '"', '\n'])), "{:?}", super::MODELS);
    }
}
