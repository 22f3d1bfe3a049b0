//! The scene file format (TOML), as serde types. See `docs/scene.md` for the user guide.
//!
//! Every table rejects unknown keys, so a typo is an error with its line, never a silently
//! ignored setting.

use serde::{Deserialize, Serialize};

use crate::fem::Locking;
use crate::mesh::CellKind;
use crate::mesh::select::{GroupRef, Region};

/// A whole scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Identification.
    pub scene: SceneInfo,
    /// The organs (at least one).
    pub organs: Vec<OrganSpec>,
    /// Surgical tools available in the scene.
    #[serde(default)]
    pub tools: Vec<ToolSpec>,
    /// Which effects the scene simulates.
    #[serde(default)]
    pub effects: Effects,
    /// Accuracy/cost settings.
    #[serde(default)]
    pub fidelity: Fidelity,
}

/// `[scene]`: identification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneInfo {
    /// Short name, used for output folders (letters, digits, `-`, `_`).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
}

/// `[[organs]]`: one deformable body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrganSpec {
    /// Name, unique in the scene.
    pub name: String,
    /// Mass density ρ (kg/m³).
    pub density: f64,
    /// Where the mesh comes from.
    pub mesh: MeshSpec,
    /// Materials by region (at least one).
    pub materials: Vec<MaterialSpec>,
    /// The supports: `[organs.fixed]`, one region held in all three components, or
    /// `[[organs.fixed]]`, a list of supports that may hold chosen components or be elastic.
    pub fixed: FixedSpec,
    /// Surface region where tools may touch.
    pub accessible: Region,
    /// Static loads applied by `vademecum solve`.
    #[serde(default)]
    pub loads: Vec<LoadSpec>,
    /// Pre-planned cuts (need `effects.cutting = true`): made by the meshless solver on a
    /// hyperelastic organ (`fidelity.solver = "meshless"`), or by the full-order XFEM on a
    /// linear one (`vademecum solve`; `[fidelity.xfem]`).
    #[serde(default)]
    pub cuts: Vec<CutSpec>,
    /// `[organs.visual]`: a finer surface drawn (and recorded) instead of the simulation
    /// mesh's, embedded in its tetrahedra and split along the cut (co-rotational cutting,
    /// `fidelity.cutting = "corotational_xfem"`).
    #[serde(default)]
    pub visual: Option<VisualSpec>,
    /// This organ's deformation model, in place of the scene's `effects.deformation`: a scene
    /// may deform one organ largely (a gallbladder retracted by a grasper) while it cuts or
    /// tears another ([`crate::scene::Scene::organ_deformation`]); the organ cut may deform
    /// largely itself.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deformation: Option<DeformationModel>,
    /// This is the organ the scalpel cuts (at most one organ; it must not tear). Default: the
    /// first organ without a damage law, a linear one first
    /// ([`crate::scene::Scene::cut_organ`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub cuttable: bool,
}

/// `[organs.visual]`: a visual surface mesh (seed 003 §3.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VisualSpec {
    /// A Wavefront `.obj` surface, relative to the scene file: closed, consistently oriented.
    pub file: String,
    /// Factor applied to its coordinates. Default: the organ mesh's `scale`, so that a
    /// surface made in the same units as the mesh lines up with it.
    #[serde(default)]
    pub scale: Option<f64>,
}

/// `fixed`: one region (all components held), or several supports.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum FixedSpec {
    /// `[organs.fixed]`: a region, every component held at zero.
    Region(Region),
    /// `[[organs.fixed]]`: several supports.
    Supports(Vec<SupportSpec>),
}

impl<'de> Deserialize<'de> for FixedSpec {
    /// A table is a region, an array of tables a list of supports; the error of the form
    /// given is reported (not serde's "no variant matched").
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            v @ toml::Value::Array(_) => Vec::<SupportSpec>::deserialize(v)
                .map(Self::Supports)
                .map_err(|e| D::Error::custom(format!("[[organs.fixed]]: {}", e.message()))),
            v => Region::deserialize(v)
                .map(Self::Region)
                .map_err(|e| D::Error::custom(format!("[organs.fixed] must be one region (box, half_space, sphere, group or nodes), or [[organs.fixed]] a list of supports: {}", e.message()))),
        }
    }
}

/// One `[[organs.fixed]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SupportSpec {
    /// Name its reaction is reported under (default `fixed`, `fixed2`, …).
    #[serde(default)]
    pub name: Option<String>,
    /// The region.
    pub region: Region,
    /// The components it acts on (default all three): `["x"]` is a roller or a symmetry
    /// plane normal to x.
    #[serde(default)]
    pub components: Option<Vec<Axis>>,
    /// An elastic foundation instead of a rigid support: springs per unit area (Pa/m) on the
    /// boundary faces of the region, on the chosen components (an organ resting on another).
    #[serde(default)]
    pub stiffness: Option<f64>,
}

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        self as usize
    }

    /// `x`, `y` or `z`, as scenes write it.
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }
}

impl FixedSpec {
    /// The supports, a single region read as one support of all three components.
    pub fn supports(&self) -> Vec<SupportSpec> {
        match self {
            Self::Region(r) => vec![SupportSpec {
                name: None,
                region: r.clone(),
                components: None,
                stiffness: None,
            }],
            Self::Supports(s) => s.clone(),
        }
    }
}

/// How a `force` load shares its total over its region.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForceDistribution {
    /// An equal share per node (simple; not consistent with the shape functions on an uneven
    /// mesh: a node with little area around it gets as much as one with much).
    #[default]
    Equal,
    /// A uniform traction `F / A` on the boundary faces of the region, integrated with the
    /// shape functions.
    Surface,
    /// A uniform force density `F / V` in the cells of the region, integrated with the shape
    /// functions (`∫ N_a dV`, exact for linear cells).
    Volume,
}

/// `[[organs.cuts]]`: a cut swept by a straight blade, in the mesh's (reference) coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutSpec {
    /// Successive blade positions, each the blade's two end points (m); each step from one
    /// position to the next sweeps a quadrilateral of the cut surface.
    pub blade: Vec<[[f64; 3]; 2]>,
}

/// Built-in procedural meshes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BuiltinMesh {
    /// A smooth organ-like lobe of tetrahedra (`semi_axes`, `bend`, `divisions`).
    Lobe,
    /// A structured box (`origin`, `size`, `divisions`, `cell`).
    Block,
    /// A thin spherical cap of hexahedra, cornea-like (`curvature_radius`, `base_radius`,
    /// `thickness`, `divisions = [n, n, layers]`); base circle at z = 0, apex up.
    Dome,
}

/// `[organs.mesh]`: a mesh file or a built-in mesh. Exactly one of `file` and `builtin`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// A `.msh`, `.vtu` or `.vtk` file, relative to the scene file.
    pub file: Option<String>,
    /// A built-in mesh.
    pub builtin: Option<BuiltinMesh>,
    /// Factor applied to the file's coordinates (e.g. 0.001 for a mesh in mm). Default 1.
    pub scale: Option<f64>,
    /// Translation applied after scaling (m). Default 0.
    pub translate: Option<[f64; 3]>,
    /// Lobe: semi-axes (m).
    pub semi_axes: Option<[f64; 3]>,
    /// Lobe: bend, as a fraction of the z semi-axis.
    pub bend: Option<f64>,
    /// Lobe or block: cell divisions along x, y, z.
    pub divisions: Option<[usize; 3]>,
    /// Block: lower corner (m).
    pub origin: Option<[f64; 3]>,
    /// Block: edge lengths (m).
    pub size: Option<[f64; 3]>,
    /// Block: cell kind (`hex8` or `tet4`). Default hex8.
    pub cell: Option<CellKind>,
    /// Dome: radius of curvature of the outer surface (m).
    pub curvature_radius: Option<f64>,
    /// Dome: radius of the base circle (m).
    pub base_radius: Option<f64>,
    /// Dome: shell thickness (m).
    pub thickness: Option<f64>,
}

/// Constitutive models a material may name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MaterialModel {
    /// Linear elasticity (small strains).
    Linear,
    /// St Venant–Kirchhoff hyperelasticity.
    Stvk,
    /// Compressible neo-Hookean hyperelasticity.
    NeoHookean,
    /// Mooney–Rivlin hyperelasticity.
    MooneyRivlin,
}

/// `[[organs.materials]]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// `"all"` (default) or a physical group name or tag.
    #[serde(default = "all_region")]
    pub region: GroupRef,
    /// Only the cells (of `region`) whose nodes all lie in this geometric region, e.g. a
    /// layer of a mesh that has no physical groups: `within = { half_space = { … } }`.
    #[serde(default)]
    pub within: Option<Region>,
    /// The constitutive model.
    pub model: MaterialModel,
    /// Young's modulus E (Pa).
    pub young: Option<f64>,
    /// Poisson's ratio ν.
    pub poisson: Option<f64>,
    /// Mooney–Rivlin c10 (Pa).
    pub c10: Option<f64>,
    /// Mooney–Rivlin c01 (Pa).
    pub c01: Option<f64>,
    /// Mooney–Rivlin bulk modulus (Pa).
    pub bulk: Option<f64>,
    /// The volumetric energy `U(J)` of `neo_hookean` and `mooney_rivlin`: `j_minus_1`
    /// (`K/2 (J − 1)²`, the default), `ln_j` (`K/2 (ln J)²`, SOFA's) or `simo_taylor`
    /// (`K/4 (J² − 1 − 2 ln J)`).
    pub volumetric: Option<crate::material::hyperelastic::VolumetricLaw>,
    /// Marks the material tearable (needs `effects.tearing = true` and `model = "linear"`):
    /// isotropic damage at its integration points (seed 000 §4.2; `docs/tearing.md`).
    #[serde(default)]
    pub damage: Option<DamageSpec>,
}

/// The form of a damage law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DamageForm {
    /// The seed's exponential potential (Eq. 4.3), `alpha` and `beta`: no threshold, no peak.
    #[default]
    Simo,
    /// A threshold and exponential softening, `strength` and `fracture_energy`, regularised
    /// by the cell size.
    Softening,
}

/// `damage = { … }` of a material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DamageSpec {
    /// `simo` (default) or `softening`.
    #[serde(default)]
    pub law: DamageForm,
    /// `simo`: α (√Pa), > 0.
    pub alpha: Option<f64>,
    /// `simo`: β in [0, 1].
    pub beta: Option<f64>,
    /// `softening`: tensile strength f_t (Pa).
    pub strength: Option<f64>,
    /// `softening`: fracture energy G_f (J/m²).
    pub fracture_energy: Option<f64>,
    /// Stiffness fraction a fully damaged point keeps (default 10⁻⁴).
    #[serde(default = "default_residual")]
    pub residual: f64,
    /// Damage at which a cell is torn: no longer rendered, and it releases a grasp (default
    /// 0.8, the seed's).
    #[serde(default = "default_torn")]
    pub torn: f64,
}

fn default_residual() -> f64 {
    crate::damage::law::DEFAULT_RESIDUAL
}
fn default_torn() -> f64 {
    crate::damage::law::DEFAULT_TORN
}

fn all_region() -> GroupRef {
    GroupRef::Name("all".into())
}

/// `[[organs.loads]]`: a static load, tagged by `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum LoadSpec {
    /// A force (N) on the node nearest to `at` (m).
    Point {
        /// Where (m); the nearest node is loaded.
        at: [f64; 3],
        /// Force (N).
        force: [f64; 3],
    },
    /// A total force (N) over a region, distributed as `distribution` says.
    Force {
        /// The region.
        region: Region,
        /// Total force (N).
        force: [f64; 3],
        /// How it is shared: `equal` (per node; the default), `surface` (a uniform traction
        /// on the region's boundary faces, consistent) or `volume` (a uniform force density
        /// in the cells whose nodes all lie in the region, consistent).
        #[serde(default)]
        distribution: ForceDistribution,
    },
    /// A uniform traction (Pa) on the boundary faces inside a region.
    Traction {
        /// The region.
        region: Region,
        /// Traction vector (Pa).
        traction: [f64; 3],
    },
    /// A uniform pressure (Pa, positive pushing into the body) on the boundary faces inside a
    /// region, normal to each face; it follows the deformed surface at large deformations.
    Pressure {
        /// The region.
        region: Region,
        /// Pressure (Pa).
        pressure: f64,
    },
    /// A body acceleration (m/s²), e.g. gravity `[0, 0, -9.81]`.
    Gravity {
        /// Acceleration (m/s²).
        acceleration: [f64; 3],
    },
    /// Prescribed displacement components (m) on the nodes of a region; omitted components
    /// stay free. Its reaction is reported under `name`.
    Displacement {
        /// Name for the reaction report.
        name: String,
        /// The region.
        region: Region,
        /// x component (m).
        x: Option<f64>,
        /// y component (m).
        y: Option<f64>,
        /// z component (m).
        z: Option<f64>,
    },
}

/// Most tools a scene names (`[[tools]]`): a session moves them together, and the contacts
/// of as many tools on one organ are solved together.
pub const MAX_TOOLS: usize = 4;

/// The largest force any tool may render (N), whatever the scene says: about ten times what
/// a desktop haptic device can display, a bound on what a client can ever receive.
pub const GLOBAL_FORCE_LIMIT_N: f64 = 100.0;

/// The probe's force limit when the scene gives none (N). Desktop haptic devices render a few
/// newtons (the bridge clamps to the device's own limit); 50 N leaves a gRPC client the
/// tissue's response far past that — the built-in organ pressed three probe radii deep at
/// its middle — while bounding what any client receives.
pub const DEFAULT_PROBE_MAX_FORCE_N: f64 = 50.0;

fn default_probe_max_force() -> f64 {
    DEFAULT_PROBE_MAX_FORCE_N
}

/// `[[tools]]`, tagged by `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ToolSpec {
    /// A rigid spherical-tip probe for palpation.
    Probe {
        /// Tool name.
        name: String,
        /// Tip radius (m).
        radius: f64,
        /// Largest force the probe renders (N): the session clamps the force's magnitude to
        /// it and flags the tick `FORCE_SATURATED`. At most [`GLOBAL_FORCE_LIMIT_N`].
        #[serde(default = "default_probe_max_force")]
        max_force: f64,
    },
    /// A scalpel.
    Scalpel {
        /// Tool name.
        name: String,
        /// Blade length (m).
        blade_length: f64,
        /// Force on the blade plane above which tissue is cut (N).
        cut_force: f64,
        /// Largest force the scalpel renders (N), as a probe's `max_force`: the session
        /// clamps the force's magnitude to it and flags the tick `FORCE_SATURATED`; the
        /// device bridge then applies its device's own limit. At most [`GLOBAL_FORCE_LIMIT_N`].
        #[serde(default = "default_probe_max_force")]
        max_force: f64,
    },
    /// A grasper.
    Grasper {
        /// Tool name.
        name: String,
        /// Jaw width (m).
        jaw_width: f64,
        /// Largest force the jaws hold before slipping (N).
        max_force: f64,
    },
}

impl SceneFile {
    /// The first scalpel's force limit (N), if the scene has a scalpel.
    pub fn scalpel_max_force(&self) -> Option<f64> {
        self.tools.iter().find_map(|t| match t {
            ToolSpec::Scalpel { max_force, .. } => Some(*max_force),
            _ => None,
        })
    }

    /// The first scalpel's blade length (m) and cut force (N), if the scene has a scalpel.
    pub fn scalpel(&self) -> Option<(f64, f64)> {
        self.tools.iter().find_map(|t| match t {
            ToolSpec::Scalpel {
                blade_length, cut_force, ..
            } => Some((*blade_length, *cut_force)),
            _ => None,
        })
    }
}

impl ToolSpec {
    /// The tool's name.
    pub fn name(&self) -> &str {
        match self {
            ToolSpec::Probe { name, .. } | ToolSpec::Scalpel { name, .. } | ToolSpec::Grasper { name, .. } => name,
        }
    }
}

/// Deformation models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeformationModel {
    /// Linear elasticity (small strains).
    #[default]
    Linear,
    /// Large deformations (hyperelastic).
    Large,
}

/// `[effects]`: what the scene simulates. A scene pays only for what it names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// Deformation model of every organ that does not name its own (`[[organs]]
    /// deformation`). Default linear.
    #[serde(default)]
    pub deformation: DeformationModel,
    /// Cutting (needs a scalpel tool).
    #[serde(default)]
    pub cutting: bool,
    /// Tearing (needs a grasper tool).
    #[serde(default)]
    pub tearing: bool,
}

/// `[fidelity]`: accuracy against cost.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fidelity {
    /// Volumetric-locking treatment: `none`, `sri`, `bbar` (hexahedra; on tetrahedra these
    /// three are the plain element) or `nodal` (the averaged-nodal-pressure tetrahedron).
    /// Default: `bbar` on hexahedra; on tetrahedra `nodal` when a material's ν exceeds 0.45,
    /// `none` otherwise ([`crate::scene::resolve_locking`]).
    #[serde(default)]
    pub locking: Option<Locking>,
    /// Settings of the PGD vademecum builder.
    #[serde(default)]
    pub pgd: PgdFidelity,
    /// Settings of the large-deformation lattice (used by the organs whose deformation is
    /// large: `effects.deformation = "large"` or the organ's own `deformation`).
    #[serde(default)]
    pub large: LargeFidelity,
    /// The solver of `vademecum solve`: finite elements (default) or the meshless reference.
    #[serde(default)]
    pub solver: SolverKind,
    /// Settings of the meshless solver.
    #[serde(default)]
    pub meshless: MeshlessFidelity,
    /// The cutting model: `pgd_xfem` (default; the reduced XFEM of seed 000, linear) or
    /// `corotational_xfem` (seed 003: the same haptic model, and a co-rotational XFEM
    /// deformation at the frame rate that a cut flap may rotate in; `docs/cutting.md`).
    #[serde(default)]
    pub cutting: CuttingModel,
    /// Settings of cutting by XFEM (linear organs).
    #[serde(default)]
    pub xfem: XfemFidelity,
    /// Settings of tearing (the damage reference, its POD and vademecum).
    #[serde(default)]
    pub tearing: TearingFidelity,
    /// What a session does when its ticks come close to missing their deadline: `auto`
    /// (default) falls back to a cheaper setting — the large-deformation law on the lattice's
    /// nearest position, the frames on the fewest modes that meet 1e-2 — says so
    /// (`EVENT_REDUCED_FIDELITY`, a metric) and returns when the load falls; `off` keeps the
    /// scene's settings throughout (a quantitative recording).
    #[serde(default)]
    pub fallback: Fallback,
}

/// `fidelity.fallback`: whether a session under load falls back to a cheaper setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Fallback {
    /// Fall back under load, return when it falls.
    #[default]
    Auto,
    /// Keep the scene's settings.
    Off,
}

/// One block of a tearing schedule: `steps` pseudo-time steps of `scale` times the organ's
/// loads (forces and prescribed displacements are per-step increments).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScheduleBlock {
    /// Number of steps.
    pub steps: usize,
    /// Multiplier of the loads at each of them (negative unloads).
    pub scale: f64,
}

/// `[fidelity.tearing]`: the offline stage of tearing (seed 000 §4.5) and the online step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TearingFidelity {
    /// The pseudo-time steps of the full-order reference whose damage fields are the POD's
    /// snapshots (default ten steps of the loads, as the seed's cube).
    #[serde(default = "default_schedule")]
    pub schedule: Vec<ScheduleBlock>,
    /// A fixed number of POD vectors (default: as many as `pod_energy` needs, at most 10).
    #[serde(default)]
    pub pod_vectors: Option<usize>,
    /// Energy fraction of the snapshots the POD basis keeps.
    #[serde(default = "default_pod_energy")]
    pub pod_energy: f64,
    /// Margin around the snapshots' coefficient box (fraction of each range).
    #[serde(default = "default_margin")]
    pub margin: f64,
    /// Grid nodes along each POD coefficient's range.
    #[serde(default = "default_grid")]
    pub grid: usize,
    /// The vademecum stops adding modes below this amplitude relative to the first.
    #[serde(default = "default_tear_tolerance")]
    pub tolerance: f64,
    /// Most vademecum modes.
    #[serde(default = "default_tear_modes")]
    pub max_modes: usize,
    /// The online integrator: `simplified` (h = 0, the seed's; default: 40 µs a step on the
    /// gallbladder) or `full` (h ≠ 0: follows the consistent-tangent scheme, which is closer
    /// to equilibrium, at ~8× the cost; `BENCHMARKS.md`).
    #[serde(default = "default_variant")]
    pub variant: crate::damage::online::Variant,
    /// Largest damage increment of an online step before it is split into sub-steps.
    #[serde(default = "default_max_dd")]
    pub max_damage_increment: f64,
    /// Most sub-steps of an online step (a power of two).
    #[serde(default = "default_max_substeps")]
    pub max_substeps: u32,
    /// Places the grasper can take hold of the tissue: the scene's load (the grasp the seed
    /// pulls by), then up to `grasp_sites − 1` more on the tearable tissue's accessible
    /// surface, farthest first and at least `jaw_width` apart (`crate::damage::sites`). Each
    /// site costs one more offline stage (reference runs, POD, vademecum) and bundle space
    /// (default 1: the scene's grasp only).
    #[serde(default = "default_grasp_sites")]
    pub grasp_sites: usize,
}

fn default_schedule() -> Vec<ScheduleBlock> {
    vec![ScheduleBlock { steps: 10, scale: 1.0 }]
}
fn default_pod_energy() -> f64 {
    1.0 - 1e-8
}
fn default_margin() -> f64 {
    0.1
}
fn default_grid() -> usize {
    201
}
fn default_tear_tolerance() -> f64 {
    1e-6
}
fn default_tear_modes() -> usize {
    60
}
fn default_variant() -> crate::damage::online::Variant {
    crate::damage::online::Variant::Simplified
}
fn default_max_dd() -> f64 {
    0.1
}
fn default_max_substeps() -> u32 {
    8
}
fn default_grasp_sites() -> usize {
    1
}

impl Default for TearingFidelity {
    fn default() -> Self {
        Self {
            schedule: default_schedule(),
            pod_vectors: None,
            pod_energy: default_pod_energy(),
            margin: default_margin(),
            grid: default_grid(),
            tolerance: default_tear_tolerance(),
            max_modes: default_tear_modes(),
            variant: default_variant(),
            max_damage_increment: default_max_dd(),
            max_substeps: default_max_substeps(),
            grasp_sites: default_grasp_sites(),
        }
    }
}

impl TearingFidelity {
    /// The multiplier of every step.
    pub fn steps(&self) -> Vec<f64> {
        self.schedule.iter().flat_map(|b| std::iter::repeat_n(b.scale, b.steps)).collect()
    }
}

/// `[fidelity.xfem]`: cutting by XFEM with cracking nodes (seed 000 chapter 3; `docs/cutting.md`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct XfemFidelity {
    /// The sliver rule: a node whose support has less than this fraction of its volume on one
    /// side of the cut is not enriched (conditioning).
    #[serde(default = "default_sliver")]
    pub sliver: f64,
    /// Move each cracked node's cut plane to pass through the node (the seed's node-centred
    /// cuts) instead of following the blade's surface.
    #[serde(default)]
    pub node_centred: bool,
    /// What happens to a piece the cuts detach from every support: `hold` (a soft foundation
    /// keeps it in place) or `remove` (also held, its loads dropped, flagged not drawn).
    #[serde(default)]
    pub detached: crate::xfem::Detached,
    /// The Ritz basis of the online model's continuous part: `srb` (modes split by
    /// component) or `prb` (one coefficient per mode).
    #[serde(default = "default_basis")]
    pub basis: crate::xfem::reduced::RitzBasis,
    /// What carries the online model's discontinuous part: `local_fields` (the seed's
    /// pre-computed local XFEM fields; exact up to the modes' error) or `bare` (the enriched
    /// shape functions alone).
    #[serde(default = "default_discontinuous")]
    pub discontinuous: crate::xfem::reduced::Discontinuous,
    /// Where the cut ends: `cracked` (seed 000's rule, every node of a cut cell, the front's
    /// included: the opening runs one ring of cells past the blade) or `shared` (the front's
    /// nodes stay shared by both sides: the cut ends where the blade stopped, on cell faces).
    #[serde(default)]
    pub front: crate::xfem::Front,
}

fn default_sliver() -> f64 {
    1e-4
}
fn default_basis() -> crate::xfem::reduced::RitzBasis {
    crate::xfem::reduced::RitzBasis::Srb
}
fn default_discontinuous() -> crate::xfem::reduced::Discontinuous {
    crate::xfem::reduced::Discontinuous::LocalFields
}

impl Default for XfemFidelity {
    fn default() -> Self {
        Self {
            sliver: default_sliver(),
            node_centred: false,
            detached: crate::xfem::Detached::Hold,
            basis: default_basis(),
            discontinuous: default_discontinuous(),
            front: crate::xfem::Front::Cracked,
        }
    }
}

impl XfemFidelity {
    /// The XFEM discretisation parameters.
    pub fn params(&self) -> crate::xfem::XfemParams {
        crate::xfem::XfemParams {
            sliver: self.sliver,
            node_centred: self.node_centred,
            detached: self.detached,
            front: self.front,
            ..crate::xfem::XfemParams::default()
        }
    }
}

/// `fidelity.cutting`: which model a cutting session runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CuttingModel {
    /// The reduced (PGD-based) linear XFEM of seed 000: force and drawn deformation.
    #[default]
    PgdXfem,
    /// Seed 003: the reduced model gives the haptic force every tick; the co-rotational XFEM
    /// of the cut organ gives the deformation on the frame thread (multi-rate), and corrects
    /// the force's compliance where it rotates.
    CorotationalXfem,
}

/// Which solver `vademecum solve` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// Finite elements: linear, or Newton–Raphson for hyperelastic organs.
    #[default]
    Fem,
    /// Element-free Galerkin with adaptive dynamic relaxation (seed 004), hyperelastic organs.
    Meshless,
}

/// `[fidelity.meshless]`: the meshless (EFG, adaptive dynamic relaxation) solver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshlessFidelity {
    /// Influence radius of each node, in mean lengths of the mesh edges at the node.
    #[serde(default = "default_support")]
    pub support: f64,
    /// Integration points per cell and axis: 1 (cell centres) or 2 (4 per tetrahedron, 8 per
    /// hexahedron; the relaxation then needs far fewer steps).
    #[serde(default = "default_integration")]
    pub integration: usize,
    /// Absolute accuracy of the displacements at which the relaxation stops (m).
    #[serde(default = "default_meshless_tolerance")]
    pub tolerance: f64,
    /// Relaxation steps over which the loads are ramped.
    #[serde(default = "default_loading_steps")]
    pub loading_steps: usize,
    /// Most relaxation steps in all.
    #[serde(default = "default_max_steps")]
    pub max_steps: usize,
}

fn default_support() -> f64 {
    2.2
}
fn default_integration() -> usize {
    2
}
fn default_meshless_tolerance() -> f64 {
    1e-7
}
fn default_loading_steps() -> usize {
    2000
}
fn default_max_steps() -> usize {
    200_000
}

impl Default for MeshlessFidelity {
    fn default() -> Self {
        Self {
            support: default_support(),
            integration: default_integration(),
            tolerance: default_meshless_tolerance(),
            loading_steps: default_loading_steps(),
            max_steps: default_max_steps(),
        }
    }
}

/// `[fidelity.large]`: the lattice of ANM-POD models (seed 001) built for large deformations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LargeFidelity {
    /// Lattice positions over the accessible surface (farthest-point sampled).
    #[serde(default = "default_large_positions")]
    pub positions: usize,
    /// Force (N) each position's path reaches; deeper presses extrapolate the law.
    #[serde(default = "default_large_force")]
    pub max_force: f64,
    /// Full Newton load steps per position (the POD snapshots).
    #[serde(default = "default_large_steps")]
    pub load_steps: usize,
    /// Most POD modes per position.
    #[serde(default = "default_large_modes")]
    pub modes: usize,
    /// Truncation order of each position's ANM series (1…8).
    #[serde(default = "default_large_order")]
    pub order: usize,
}

fn default_large_positions() -> usize {
    16
}
fn default_large_force() -> f64 {
    2.0
}
fn default_large_steps() -> usize {
    6
}
fn default_large_modes() -> usize {
    9
}
fn default_large_order() -> usize {
    6
}

impl Default for LargeFidelity {
    fn default() -> Self {
        Self {
            positions: default_large_positions(),
            max_force: default_large_force(),
            load_steps: default_large_steps(),
            modes: default_large_modes(),
            order: default_large_order(),
        }
    }
}

/// `[fidelity.pgd]`: stopping criteria of the PGD greedy enrichment (seed 000, Alg. 2.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PgdFidelity {
    /// Target relative L2 error of the displacement field over all load states, measured
    /// against the exact solution during the build; the bundle keeps the fewest modes that
    /// meet it.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Global tolerance ε_R of the greedy enrichment: stop adding modes when a new mode's
    /// energy falls below this fraction of the first's.
    #[serde(default = "default_eps_r")]
    pub global_tolerance: f64,
    /// Fixed-point tolerance ε_F on the change of a mode between alternating iterations.
    #[serde(default = "default_eps_f")]
    pub enrichment_tolerance: f64,
    /// Cap on the number of modes.
    #[serde(default = "default_max_modes")]
    pub max_modes: usize,
    /// Cap on alternating fixed-point iterations per mode.
    #[serde(default = "default_max_iters")]
    pub max_iterations: usize,
    /// Modes enriched together (1: Alg. 2.1 as published; larger blocks turn single solves
    /// into blocked ones and build several times faster at the same accuracy).
    #[serde(default = "default_block")]
    pub block: usize,
}

fn default_tolerance() -> f64 {
    1e-3
}
fn default_eps_r() -> f64 {
    1e-4
}
fn default_eps_f() -> f64 {
    1e-2
}
fn default_max_modes() -> usize {
    2000
}
fn default_max_iters() -> usize {
    3
}
fn default_block() -> usize {
    32
}

impl Default for PgdFidelity {
    fn default() -> Self {
        Self {
            tolerance: default_tolerance(),
            global_tolerance: default_eps_r(),
            enrichment_tolerance: default_eps_f(),
            max_modes: default_max_modes(),
            max_iterations: default_max_iters(),
            block: default_block(),
        }
    }
}
