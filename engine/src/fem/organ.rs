//! The finite-element problem an organ becomes: its mesh, materials (linear moduli and, when
//! hyperelastic, the laws), locking treatment, constraints and loads, the regions whose
//! reactions are reported, the surface tools may touch. A scene makes it
//! ([`crate::scene::Scene::organ_model`]); every method (`pgd`, `rom`, `xfem`, `damage`,
//! `meshless`) builds from it, so none of them reads a scene.

use super::Locking;
use super::assembly::MaterialMap;
use super::hyperelastic::LawMap;
use super::linear_static::StaticProblem;
use crate::mesh::Mesh;
use crate::mesh::boundary::Boundary;

/// One organ of a scene, ready for a static solve: what every method builds from
/// ([`crate::scene::Scene::organ_model`] makes it).
#[derive(Debug, Clone)]
pub struct OrganModel {
    /// Organ name.
    pub name: String,
    /// Its mesh (m).
    pub mesh: Mesh,
    /// Materials per cell (for hyperelastic organs, their small-strain moduli: what the
    /// linear vademecum and the mass use).
    pub materials: MaterialMap,
    /// Hyperelastic laws per cell, when the organ's materials are hyperelastic (`None`:
    /// linear elasticity).
    pub laws: Option<LawMap>,
    /// Locking treatment (the scene's, or the default for the mesh and materials).
    pub locking: Locking,
    /// What the user should know before trusting the results (an element that will lock).
    pub warnings: Vec<String>,
    /// Constraints and loads.
    pub problem: StaticProblem,
    /// Regions whose reactions are reported: `fixed`, then each displacement load's name.
    pub named_regions: Vec<(String, Vec<usize>)>,
    /// Surface nodes tools may touch.
    pub accessible_nodes: Vec<usize>,
    /// The boundary surface.
    pub boundary: Boundary,
}
