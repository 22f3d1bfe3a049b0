//! Tearing by continuum damage (seed 000 ch. 4) on a unit block on three rollers, its top
//! pulled: a layer softened all the way to its residual stiffness (D → 1) by the explicit and
//! Newton references, ν = 0.499 under damage by the POD–PGD integrator against Newton, the
//! integrator pulled three times farther than its snapshots went (its coefficients leave the
//! vademecum's box: clamped and reported, never extrapolated), and a whole schedule asked in one
//! step (sub-stepped to the limit, then flagged).

use std::sync::Arc;

use super::{Case, Expect, Outcome, Size, diagnostic, finite, outcome};
use crate::damage::build::{self, TearSettings};
use crate::damage::law::DamageLaw;
use crate::damage::model::TearModel;
use crate::damage::online::{OnlineTear, StepLimits, Variant};
use crate::damage::points::MaterialPoints;
use crate::damage::reference::{self, RunSettings, Scheme, Tangent};
use crate::fem::assembly::MaterialMap;
use crate::material::LinearElastic;
use crate::mesh::procedural;

/// A unit block of `n³` hexahedra (E = 5 Pa, Poisson `nu`), the cells `tearable` picks
/// tearable with `law`, on rollers at x = 0, y = 0, z = 0, its top pulled by 1 per unit step.
fn pulled_block(n: usize, nu: f64, law: DamageLaw, tearable: impl Fn(usize) -> bool) -> Result<TearModel, Outcome> {
    let mesh = procedural::block_hex([0.0; 3], [1.0; 3], [n; 3]);
    let mat = MaterialMap::uniform(LinearElastic::new(5.0, nu).map_err(diagnostic)?, 1.0, mesh.n_cells());
    let pts = MaterialPoints::new(&mesh, &mat, true, |c, _| Ok::<_, ()>(tearable(c).then_some(law)))
        .map_err(|_| Outcome::Broken("material points".into()))?;
    let nd = 3 * mesh.n_nodes();
    let (mut constrained, mut prescribed) = (vec![false; nd], vec![0.0; nd]);
    for (a, x) in mesh.nodes.iter().enumerate() {
        for i in 0..3 {
            constrained[3 * a + i] |= x[i] == 0.0;
        }
        if x[2] == 1.0 {
            constrained[3 * a + 2] = true;
            prescribed[3 * a + 2] = 1.0;
        }
    }
    Ok(TearModel::new(mesh, pts, &constrained, vec![0.0; nd], prescribed))
}

fn layer_torn(size: Size) -> Outcome {
    outcome(|| {
        let n = size.pick(3, 6);
        let law = DamageLaw::softening(5.0, 0.5, 0.02, 1.0 / 3.0, 1e-6).map_err(diagnostic)?;
        // one layer of cells in the middle (two softening layers would share the localisation
        // and leave Newton a non-unique softening branch to find)
        let mut model = pulled_block(n, 0.3, law, |c| c / (n * n) == n / 2)?;
        model.schedule = [vec![0.01; 20], vec![0.05; 40]].concat();
        let mut summary = Vec::new();
        for scheme in [Scheme::Explicit(Tangent::Secant), Scheme::Newton] {
            let run = reference::run(&model, RunSettings::seed(scheme), |_, _| {}).map_err(diagnostic)?;
            let last = run.steps.last().ok_or_else(|| Outcome::Broken("no steps".into()))?;
            if !(finite(&last.u) && last.stored.is_finite() && last.stored >= 0.0) || last.max_damage < 1.0 - 1e-5 {
                return Ok(Outcome::Broken(format!(
                    "{scheme:?}: D = {}, stored {} J",
                    last.max_damage, last.stored
                )));
            }
            summary.push(format!(
                "{scheme:?}: D = 1 − {:.0e}, {} cells torn",
                1.0 - last.max_damage,
                last.torn_cells
            ));
        }
        Ok(Outcome::bounded(summary.join("; ")))
    })
}

fn incompressible(size: Size) -> Outcome {
    outcome(|| {
        let law = DamageLaw::simo(0.4, 0.1, 1e-4).map_err(diagnostic)?;
        let mut model = pulled_block(size.pick(2, 3), 0.499, law, |_| true)?;
        let steps = 10;
        model.schedule = vec![0.02; steps];
        let (off, _, runs) = build::build(model, &TearSettings::default(), |_, _| {}).map_err(diagnostic)?;
        let mut online = OnlineTear::new(Arc::new(off), Variant::Simplified, StepLimits::default());
        let mut worst: f64 = 0.0;
        for k in 0..steps {
            online.step(0.02);
            let u = online.displacement_vec();
            if !finite(&u) {
                return Ok(Outcome::Broken(format!("step {}: non-finite displacement", k + 1)));
            }
            worst = worst.max(reference::l2_error(&u, &runs[0].steps[k + 1].u).1);
        }
        let d = runs[0].steps[steps].max_damage;
        Ok(Outcome::answer(
            format!("{steps} steps, damage up to {d:.2}, against Newton"),
            worst,
        ))
    })
}

fn outside_box(_: Size) -> Outcome {
    outcome(|| {
        let law = DamageLaw::simo(0.4, 0.1, 1e-4).map_err(diagnostic)?;
        let mut model = pulled_block(1, 0.3, law, |_| true)?;
        model.schedule = vec![0.05; 10];
        let mut s = TearSettings::default();
        s.pod.max_modes = 3;
        s.pod.energy = 1.0;
        let (off, _, _) = build::build(model, &s, |_, _| {}).map_err(diagnostic)?;
        let mut online = OnlineTear::new(Arc::new(off), Variant::Simplified, StepLimits::default());
        let (mut outside, mut clamped) = (0, 0);
        for _ in 0..30 {
            let step = online.step(0.05);
            if step.clamped && !step.outside {
                return Ok(Outcome::Broken("clamped inside the box".into()));
            }
            outside += step.outside as usize;
            clamped += step.clamped as usize;
        }
        if outside == 0 || !finite(&online.displacement_vec()) {
            return Ok(Outcome::Broken(format!("{outside} steps reported outside the box")));
        }
        Ok(Outcome::bounded(format!(
            "trained on 10 steps, run for 30: {outside} steps reported outside the box, {clamped} clamped, finite"
        )))
    })
}

fn too_fast(_: Size) -> Outcome {
    outcome(|| {
        let law = DamageLaw::simo(0.4, 0.1, 1e-4).map_err(diagnostic)?;
        let mut model = pulled_block(1, 0.3, law, |_| true)?;
        model.schedule = vec![0.05; 10];
        let (off, _, _) = build::build(model, &TearSettings::default(), |_, _| {}).map_err(diagnostic)?;
        let limits = StepLimits {
            max_damage_increment: 0.01,
            max_substeps: 4,
        };
        let mut online = OnlineTear::new(Arc::new(off), Variant::Simplified, limits);
        let step = online.step(0.5);
        if !finite(&online.displacement_vec()) {
            return Ok(Outcome::Broken("non-finite displacement".into()));
        }
        if !step.too_fast {
            return Ok(Outcome::Broken(format!("not flagged: {step:?}")));
        }
        Ok(Outcome::Diagnostic(format!(
            "too fast: {} sub-steps, damage increment {:.3} > {}",
            step.substeps, step.max_damage_increment, limits.max_damage_increment
        )))
    })
}

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "a layer damaged to D → 1",
            method: "damage references (explicit, Newton)",
            expect: Expect::FINITE,
            run: layer_torn,
        },
        Case {
            name: "ν = 0.499 under damage",
            method: "POD–PGD damage integrator, B-bar",
            // the POD truncation of the seed's cube: well under a per cent
            expect: Expect::within(1e-2),
            run: incompressible,
        },
        Case {
            name: "pulled 3× past its snapshots",
            method: "POD–PGD damage integrator",
            expect: Expect::FINITE,
            run: outside_box,
        },
        Case {
            name: "a whole schedule in one step",
            method: "POD–PGD damage integrator",
            expect: Expect::Diagnostic(&["too fast"]),
            run: too_fast,
        },
    ]
}
