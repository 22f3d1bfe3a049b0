//! A scene's tearable organ as a [`TearModel`], and the scene's tearing settings.
//!
//! The organ's supports hold, its loads (`[[organs.loads]]`: forces, pressures, prescribed
//! displacements) are the increment of one pseudo-time step, scaled at each step by
//! `[fidelity.tearing] schedule`. Materials with `damage = { … }` tear at their integration
//! points; the others never damage. Hexahedra use B̄ unless the scene asks `locking = "none"`
//! (the seed's standard hexahedron); tetrahedra are the plain constant-strain element (the
//! averaged nodal pressure is not extended to damage: a warning says so above ν = 0.45).

use super::schema::{DamageForm, DamageSpec};
use super::{Scene, SceneError, locate::Seg};
use crate::damage::build::TearSettings;
use crate::damage::law::DamageLaw;
use crate::damage::model::TearModel;
use crate::damage::online::StepLimits;
use crate::damage::points::{MaterialPoints, PointsError};
use crate::damage::sites::{self, SiteLoad};
use crate::fem::Locking;
use crate::mesh::CellKind;
use crate::rom::pod::PodCriterion;

/// The index of the first organ with a tearable material.
pub fn tearable_organ(scene: &Scene) -> Option<usize> {
    scene
        .spec
        .organs
        .iter()
        .position(|o| o.materials.iter().any(|m| m.damage.is_some()))
}

/// The tearing problem of organ `index`, with the warnings the user should read.
pub fn tear_model(scene: &Scene, index: usize) -> Result<(TearModel, Vec<String>), SceneError> {
    let organ = scene.organ_model(index)?;
    let specs = &scene.spec.organs[index].materials;
    let mut warnings = organ.warnings.clone();
    if organ.mesh.kind == CellKind::Tet4 && organ.locking == Locking::Nodal {
        warnings.push(format!(
            "organ '{}': tearing uses the plain linear tetrahedron (the averaged nodal pressure is not extended to damage), which is too stiff at ν = {:.3}",
            organ.name,
            organ.materials.table.iter().map(|m| m.poisson).fold(0.0, f64::max)
        ));
    }
    let bbar = organ.locking != Locking::None;
    let mut torn = vec![f64::INFINITY; organ.mesh.n_cells()];
    let points = MaterialPoints::new(&organ.mesh, &organ.materials, bbar, |c, size| {
        let m = organ.materials.of_cell[c] as usize;
        let Some(d) = &specs[m].damage else { return Ok(None) };
        torn[c] = d.torn;
        law(d, organ.materials.table[m].young, size).map(Some).map_err(|e| (m, e))
    })
    .map_err(|e| match e {
        PointsError::Cell { cell, source } => scene.error_at(
            &[Seg::Key("organs"), Seg::Index(index), Seg::Key("mesh")],
            format!("cell {cell}: {source}"),
        ),
        PointsError::Law((m, e)) => scene.error_at(
            &[
                Seg::Key("organs"),
                Seg::Index(index),
                Seg::Key("materials"),
                Seg::Index(m),
                Seg::Key("damage"),
            ],
            e.to_string(),
        ),
    })?;
    let p = &organ.problem;
    let mut model = TearModel::new(organ.mesh, points, &p.constrained, p.forces.clone(), p.prescribed.clone());
    model.springs = p.springs.clone();
    model.torn = torn;
    model.schedule = scene.spec.fidelity.tearing.steps();
    Ok((model, warnings))
}

/// The jaw width of the scene's grasper (its first grasper tool; m).
pub fn jaw_width(scene: &Scene) -> Option<f64> {
    scene.spec.tools.iter().find_map(|t| match t {
        crate::scene::schema::ToolSpec::Grasper { jaw_width, .. } => Some(*jaw_width),
        _ => None,
    })
}

/// The grasp sites of organ `index` beside the scene's own (its load), as many as
/// `[fidelity.tearing] grasp_sites` asks (less where the accessible tearable surface is
/// covered sooner): [`crate::damage::sites`]. `model` is the organ's [`tear_model`].
pub fn extra_sites(scene: &Scene, index: usize, model: &TearModel) -> Result<Vec<SiteLoad>, SceneError> {
    let wanted = scene.spec.fidelity.tearing.grasp_sites;
    let Some(jaw) = jaw_width(scene).filter(|_| wanted > 1) else {
        return Ok(Vec::new());
    };
    let organ = scene.organ_model(index)?;
    let candidates = sites::candidates(model, &organ.boundary, &organ.accessible_nodes, jaw);
    Ok(sites::extra_sites(model, &organ.boundary, &candidates, jaw, wanted - 1))
}

/// The law of a `damage = { … }` entry for a material of Young's modulus `young` in a cell of
/// size `size`.
pub fn law(d: &DamageSpec, young: f64, size: f64) -> Result<DamageLaw, crate::damage::law::LawError> {
    match d.law {
        DamageForm::Simo => DamageLaw::simo(d.alpha.unwrap_or(0.0), d.beta.unwrap_or(0.0), d.residual),
        DamageForm::Softening => DamageLaw::softening(young, d.strength.unwrap_or(0.0), d.fracture_energy.unwrap_or(0.0), size, d.residual),
    }
}

/// The offline settings and the online step limits of the scene.
pub fn settings(scene: &Scene) -> (TearSettings, StepLimits) {
    let t = &scene.spec.fidelity.tearing;
    let mut s = TearSettings {
        pod: PodCriterion {
            energy: t.pod_energy,
            max_modes: t.pod_vectors.unwrap_or(10),
        },
        margin: t.margin,
        ..TearSettings::default()
    };
    if t.pod_vectors.is_some() {
        s.pod.energy = 1.0;
    }
    s.vademecum.grid = t.grid;
    s.vademecum.tolerance = t.tolerance;
    s.vademecum.max_modes = t.max_modes;
    (
        s,
        StepLimits {
            max_damage_increment: t.max_damage_increment,
            max_substeps: t.max_substeps,
        },
    )
}
