//! The full-order check of a palpation lattice ([`AnmLattice`], seed 001 §6): the full
//! model's force–depth laws ([`NewtonLaw`]) at surface nodes off the lattice, and the largest
//! relative error of the force the lattice serves there, blending its [`NEIGHBOURS`] nearest
//! positions as a session does. It is what `build --target-error` holds a lattice to
//! ([`AnmLattice::build_for_target`]) and what `vademecum study` reports as the lattice's
//! largest error (the study's samples, with their error estimates, are
//! `crate::study::estimate`'s).

use super::palpation::{AnmLattice, AnmLatticeParams, NewtonLaw, loadable_nodes, surface_normals};
use super::study::StudyError;
use crate::fem::OrganModel;
use crate::rng::Rng;

/// Lattice positions blended per evaluation (seed 001 §6.1 interpolates among four).
pub const NEIGHBOURS: usize = 4;

/// How far past the lattice's force the full model is pushed to sample the extrapolation.
pub const PAST_THE_LATTICE: f64 = 1.5;

/// Full-order laws a lattice built for a target error is checked at
/// ([`AnmLattice::build_for_target`]): as many nodes as the study samples by default.
pub const LATTICE_CHECK_NODES: usize = 12;

/// Whether a state at the fraction `lambda` of a law pushed [`PAST_THE_LATTICE`] times past
/// the lattice's force is within the lattice's force.
pub fn is_within_force(lambda: f64) -> bool {
    lambda * PAST_THE_LATTICE <= 1.0 + 1e-9
}

/// The largest relative error of the force `lattice` serves (blending [`NEIGHBOURS`]
/// positions) against the full-order laws `truth` ([`newton_laws`]) over their states within
/// the lattice's force ([`is_within_force`]). Infinite without such a state; NaN when a served
/// force is.
pub fn lattice_error(lattice: &AnmLattice, truth: &[NewtonLaw]) -> f64 {
    let mut zeta = vec![0.0; lattice.max_modes()];
    let mut worst: Option<f64> = None;
    for law in truth {
        for (lambda, depth, exact) in law.ratios() {
            if !is_within_force(lambda) {
                continue;
            }
            let served = lattice.stiffness_ratio(law.point, depth, NEIGHBOURS, &mut zeta).ratio;
            let error = (served - exact).abs() / exact.abs().max(f64::MIN_POSITIVE);
            worst = Some(worst.map_or(error, |w| if error.total_cmp(&w).is_gt() { error } else { w }));
        }
    }
    worst.unwrap_or(f64::INFINITY)
}

/// The full model's force–depth laws ([`NewtonLaw`]) at `nodes` surface nodes drawn at random
/// (repeatably) among the loadable nodes not in `exclude`, with a lattice position's load
/// (`params`) pushed [`PAST_THE_LATTICE`] times past its force, on the lattice's own law (St
/// Venant–Kirchhoff with the materials' E and ν, [`crate::rom::palpation::svk_laws`]). `progress(done, total)` after
/// each node; nodes where Newton converges no step are skipped.
pub fn newton_laws(
    model: &OrganModel,
    params: &AnmLatticeParams,
    exclude: &[usize],
    nodes: usize,
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<NewtonLaw>, StudyError> {
    // the lattice's own law, whatever model the materials name (a linear organ that deforms
    // largely included)
    let laws = &crate::rom::palpation::svk_laws(model);
    let normals = surface_normals(model);
    let mut pool: Vec<usize> = loadable_nodes(model, &normals)
        .into_iter()
        .filter(|n| !exclude.contains(n))
        .collect();
    let mut rng = Rng(0x1A77_1CE5_EED5);
    let mut chosen = Vec::new();
    while chosen.len() < nodes && !pool.is_empty() {
        chosen.push(pool.swap_remove((rng.next_u64() % pool.len() as u64) as usize));
    }
    let past = AnmLatticeParams {
        max_force: PAST_THE_LATTICE * params.max_force,
        load_steps: (PAST_THE_LATTICE * params.load_steps as f64).ceil() as usize,
        ..*params
    };
    let mut out = Vec::with_capacity(chosen.len());
    for (done, &node) in chosen.iter().enumerate() {
        match NewtonLaw::at(model, laws, &past, node) {
            Ok(law) => out.push(law),
            Err(StudyError::Newton(_)) => {}
            Err(e) => return Err(e),
        }
        progress(done + 1, chosen.len());
    }
    Ok(out)
}
