//! Tearing's hard cases (issue 17): damage → 1 over a region, every cell damaged,
//! near-incompressible tissue, coefficients outside the vademecum's box, a pull faster than one
//! step can follow, and damage parameters out of range in a scene. Each must give a finite,
//! bounded answer or a clear, typed refusal.

use std::sync::Arc;

use vademecum_engine::damage::build::{self, TearSettings};
use vademecum_engine::damage::law::DamageLaw;
use vademecum_engine::damage::model::TearModel;
use vademecum_engine::damage::online::{OnlineTear, StepLimits, Variant};
use vademecum_engine::damage::points::MaterialPoints;
use vademecum_engine::damage::reference::{self, RunSettings, Scheme, Tangent};
use vademecum_engine::fem::assembly::MaterialMap;
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::procedural;
use vademecum_engine::scene::Scene;

/// A unit block of `n³` hexahedra (E = 5 Pa, Poisson `nu`), every cell tearable with `law`
/// (or only the cells `tearable` picks), held on x = 0, y = 0, z = 0 (rollers) and its top
/// z = 1 pulled by a prescribed `uz` of 1 per unit step.
fn pulled_block(n: usize, nu: f64, law: DamageLaw, tearable: impl Fn(usize) -> bool) -> TearModel {
    let mesh = procedural::block_hex([0.0; 3], [1.0; 3], [n; 3]);
    let mat = MaterialMap::uniform(LinearElastic::new(5.0, nu).unwrap(), 1.0, mesh.n_cells());
    let pts = MaterialPoints::new(&mesh, &mat, true, |c, _| Ok::<_, ()>(tearable(c).then_some(law))).unwrap();
    let nd = 3 * mesh.n_nodes();
    let (mut constrained, mut prescribed) = (vec![false; nd], vec![0.0; nd]);
    for (a, x) in mesh.nodes.iter().enumerate() {
        for i in 0..3 {
            if x[i] == 0.0 {
                constrained[3 * a + i] = true;
            }
        }
        if x[2] == 1.0 {
            constrained[3 * a + 2] = true;
            prescribed[3 * a + 2] = 1.0;
        }
    }
    TearModel::new(mesh, pts, &constrained, vec![0.0; nd], prescribed)
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

#[test]
fn a_fully_damaged_region_keeps_a_positive_stiffness_and_finite_answers() {
    // the middle layer of a 3 × 3 × 3 block softens to its residual (10⁻⁶): D → 1 there
    let law = DamageLaw::softening(5.0, 0.5, 0.02, 1.0 / 3.0, 1e-6).unwrap();
    let mut model = pulled_block(3, 0.3, law, |c| (c / 9) == 1);
    model.schedule = [vec![0.01; 20], vec![0.05; 40]].concat();
    for scheme in [Scheme::Explicit(Tangent::Secant), Scheme::Newton] {
        let run = reference::run(&model, RunSettings::seed(scheme), |_, _| {}).unwrap();
        let last = run.steps.last().unwrap();
        assert!(last.max_damage > 1.0 - 1e-5, "{scheme:?}: D = {}", last.max_damage);
        assert!(finite(&last.u), "{scheme:?}");
        // the reaction falls to what the residual stiffness carries, never negative or NaN
        assert!(last.torn_cells == 9, "{scheme:?}: the whole layer torn, {}", last.torn_cells);
        assert!(last.stored.is_finite() && last.stored >= 0.0);
    }
}

#[test]
fn every_cell_damaged_still_solves() {
    // the seed's law with beta = 0 on every cell: the whole block goes soft
    let law = DamageLaw::simo(0.1, 0.0, 1e-4).unwrap();
    let mut model = pulled_block(2, 0.3, law, |_| true);
    model.schedule = vec![0.1; 30];
    let run = reference::run(&model, RunSettings::seed(Scheme::Newton), |_, _| {}).unwrap();
    let last = run.steps.last().unwrap();
    assert!(last.cell_damage.iter().all(|&d| d > 0.8), "{:?}", last.cell_damage);
    assert!(finite(&last.u));
    // and the POD–PGD integrator over it
    let settings = TearSettings::default();
    let (off, report, _) = build::build(model, &settings, |_, _| {}).unwrap();
    assert!(report.min_g_over_box > 0.0, "the box keeps the stiffness positive");
    let mut online = OnlineTear::new(Arc::new(off), Variant::Simplified, StepLimits::default());
    for _ in 0..30 {
        online.step(0.1);
    }
    assert!(finite(&online.displacement_vec()));
}

#[test]
fn near_incompressible_tissue_damages_with_bbar_and_stays_finite() {
    let law = DamageLaw::simo(0.4, 0.1, 1e-4).unwrap();
    let mut model = pulled_block(2, 0.499, law, |_| true);
    model.schedule = vec![0.02; 10];
    let newton = reference::run(&model, RunSettings::seed(Scheme::Newton), |_, _| {}).unwrap();
    let last = newton.steps.last().unwrap();
    assert!(finite(&last.u) && last.max_damage > 0.1, "D = {}", last.max_damage);
    let (off, report, runs) = build::build(model, &TearSettings::default(), |_, _| {}).unwrap();
    let mut online = OnlineTear::new(Arc::new(off), Variant::Simplified, StepLimits::default());
    for (k, &ds) in [0.02; 10].iter().enumerate() {
        online.step(ds);
        let (_, rel) = reference::l2_error(&online.displacement_vec(), &runs[0].steps[k + 1].u);
        // the same POD truncation as the seed's cube: well under a percent
        assert!(rel < 1e-2, "step {}: {rel:e} (vademecum {:e})", k + 1, report.vademecum_error);
    }
}

#[test]
fn coefficients_outside_the_box_are_clamped_and_reported_never_extrapolated() {
    // trained on 10 steps, run for 30: the damage leaves what the snapshots saw
    let law = DamageLaw::simo(0.4, 0.1, 1e-4).unwrap();
    let mut model = pulled_block(1, 0.3, law, |_| true);
    model.schedule = vec![0.05; 10];
    let mut s = TearSettings::default();
    s.pod.max_modes = 3;
    s.pod.energy = 1.0;
    let (off, _, _) = build::build(model, &s, |_, _| {}).unwrap();
    let off = Arc::new(off);
    let mut online = OnlineTear::new(off.clone(), Variant::Simplified, StepLimits::default());
    let (mut outside, mut clamped) = (0, 0);
    for _ in 0..30 {
        let step = online.step(0.05);
        outside += step.outside as u32;
        clamped += step.clamped as u32;
        assert!(!step.clamped || step.outside, "clamped only outside the box");
    }
    assert!(outside > 0 && clamped > 0, "the run left the box and said so");
    assert!(finite(&online.displacement_vec()));
    // clamped: the coefficients the vademecum sees are the box's, whatever ξ is
    let mut a = vec![0.0; off.vademecum.n_modes];
    let mut b = vec![0.0; off.vademecum.n_modes];
    let far: Vec<f64> = off.basis.hi.iter().map(|h| h + 100.0).collect();
    assert!(off.vademecum.coefficients(&far, &mut a));
    assert!(!off.vademecum.coefficients(&off.basis.hi, &mut b));
    assert_eq!(a, b);
}

#[test]
fn a_pull_faster_than_a_step_can_follow_is_sub_stepped_then_reported() {
    let law = DamageLaw::simo(0.4, 0.1, 1e-4).unwrap();
    let mut model = pulled_block(1, 0.3, law, |_| true);
    model.schedule = vec![0.05; 10];
    let (off, _, _) = build::build(model, &TearSettings::default(), |_, _| {}).unwrap();
    let off = Arc::new(off);
    // a whole schedule in one step: split into sub-steps up to the limit, then flagged
    let limits = StepLimits {
        max_damage_increment: 0.01,
        max_substeps: 4,
    };
    let mut online = OnlineTear::new(off.clone(), Variant::Simplified, limits);
    let step = online.step(0.5);
    assert_eq!(step.substeps, 4);
    assert!(step.too_fast && step.max_damage_increment > 0.01, "{step:?}");
    assert!(finite(&online.displacement_vec()));
    // a slow pull takes one step, without the flag
    let mut online = OnlineTear::new(off, Variant::Simplified, StepLimits::default());
    let step = online.step(0.005);
    assert!(!step.too_fast && step.substeps == 1, "{step:?}");
}

#[test]
fn damage_parameters_out_of_range_are_refused_with_their_key() {
    let base = Scene::builtin("cube_tear").unwrap().source;
    for (from, to, key) in [
        ("alpha = 0.4, beta = 0.4", "alpha = -1.0, beta = 0.4", "alpha"),
        ("alpha = 0.4, beta = 0.4", "alpha = 0.4, beta = 1.5", "beta"),
        ("alpha = 0.4, beta = 0.4", "alpha = 0.4", "beta"),
        ("alpha = 0.4, beta = 0.4", "alpha = 0.4, beta = 0.4, strength = 3.0", "strength"),
        ("alpha = 0.4, beta = 0.4", "alpha = 0.4, beta = 0.4, residual = 0.0", "residual"),
    ] {
        let text = base.replace(from, to);
        let e = Scene::from_toml(&text, "cube.toml").unwrap_err();
        let path = e.key.clone().unwrap_or_default();
        // the key itself, or (a missing key) the damage table with the key named
        let named = path.ends_with(key) || (path.ends_with("damage") && e.to_string().contains(&format!("`{key}`")));
        assert!(path.contains("damage") && named, "{to}: key {path:?}: {e}");
    }
}
