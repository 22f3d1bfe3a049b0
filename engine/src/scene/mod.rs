//! Scene files: parsing, validation with file/key/line diagnostics, built-in scenes, and the
//! translation of an organ into a static finite-element problem.
//!
//! # Layout
//! - [`schema`]: the serde types of the TOML format (documented in `docs/scene.md`).
//! - [`locate`]: maps a key path to its line in the source text.
//! - this file: [`Scene`] (a validated scene), [`SceneError`], the organ a scene describes as
//!   the finite-element problem [`OrganModel`] (`crate::fem::organ`), and [`builtin`] scenes.

pub mod schema;

mod builtin_scenes;
pub mod keys;
pub mod locate;
pub mod tearing;

use std::fmt;
use std::path::{Path, PathBuf};

use crate::damage::law::{DamageLaw, LawError};
use crate::fem::assembly::MaterialMap;
use crate::fem::hyperelastic::LawMap;
use crate::fem::linear_static::StaticProblem;
use crate::fem::organ::OrganModel;
use crate::fem::{Locking, loads};
use crate::geometry::cut::Cut;
use crate::material::hyperelastic::Hyperelastic;
use crate::material::{self, LinearElastic};
use crate::mesh::boundary::Boundary;
use crate::mesh::select::{GroupRef, Region, nearest_node};
use crate::mesh::{self, CellKind, Mesh, procedural};
pub use builtin_scenes::{BUILTIN_NAMES, builtin};
use locate::Seg;
use schema::*;

/// A scene that could not be read or is inconsistent: where, and what.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The scene file (or `<builtin:NAME>`).
    pub file: PathBuf,
    /// 1-based line of the offending key, when known.
    pub line: Option<usize>,
    /// Dotted key path (`organs[0].materials[1].poisson`), when known.
    pub key: Option<String>,
    /// What is wrong, and how to fix it where a fix is obvious.
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "{k}: ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for SceneError {}

/// A parsed and validated scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The scene's content.
    pub spec: SceneFile,
    /// Where it came from (for messages and relative paths).
    pub origin: PathBuf,
    /// Its source text (for locating keys in messages, and for hashing).
    pub source: String,
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let text = crate::files::read_regular_text(path, crate::files::MAX_SCENE_BYTES).map_err(|e| SceneError {
            file: path.to_path_buf(),
            line: None,
            key: None,
            message: format!("cannot read scene file: {e}"),
        })?;
        Self::from_toml(&text, path)
    }

    /// Parses and validates scene text; `origin` names it in messages and anchors relative
    /// mesh paths.
    pub fn from_toml(text: &str, origin: impl AsRef<Path>) -> Result<Self, SceneError> {
        let origin = origin.as_ref().to_path_buf();
        let spec: SceneFile = toml::from_str(text).map_err(|e| SceneError {
            file: origin.clone(),
            line: e.span().map(|s| locate::line_of_offset(text, s.start)),
            key: None,
            message: e.message().trim().to_string(),
        })?;
        let scene = Scene {
            spec,
            origin,
            source: text.to_string(),
        };
        scene.validate()?;
        Ok(scene)
    }

    /// A built-in scene by name (see [`BUILTIN_NAMES`]).
    pub fn builtin(name: &str) -> Result<Self, SceneError> {
        let text = builtin(name).ok_or_else(|| SceneError {
            file: PathBuf::from(format!("<builtin:{name}>")),
            line: None,
            key: None,
            message: format!("no built-in scene named '{name}' (known: {})", BUILTIN_NAMES.join(", ")),
        })?;
        Self::from_toml(text, format!("<builtin:{name}>"))
    }

    /// Whether what is built for `other` is what is built for this scene: the same scene but
    /// for what a session reads at run time only — `fidelity.fallback`, the description — and
    /// the text's comments and layout. A bundle built from either serves both, so changing
    /// a runtime setting never forces a rebuild ([`crate::bundle::check_matches`]).
    pub fn builds_like(&self, other: &SceneFile) -> bool {
        let built = |s: &SceneFile| {
            let mut s = s.clone();
            s.fidelity.fallback = schema::Fallback::default();
            s.scene.description.clear();
            s
        };
        built(&self.spec) == built(other)
    }

    /// The cells organ `organ`'s built-in mesh will have, counted from its settings without
    /// making it (`None`: a mesh file, or no such organ) — what a server checks before it
    /// spends memory on a client's scene.
    pub fn builtin_cells(&self, organ: usize) -> Option<usize> {
        let m = &self.spec.organs.get(organ)?.mesh;
        let d = match (m.builtin?, m.divisions) {
            (_, Some(d)) => d,
            (BuiltinMesh::Block, None) => DEFAULT_BLOCK_DIVISIONS,
            (BuiltinMesh::Lobe, None) => procedural::LobeParams::default().divisions,
            (BuiltinMesh::Dome, None) => procedural::DomeParams::default().divisions,
        };
        Some(d.iter().product::<usize>().saturating_mul(cells_per_division(m)))
    }

    /// An error located at `path` in this scene's source.
    pub fn error_at(&self, path: &[Seg<'_>], message: impl Into<String>) -> SceneError {
        SceneError {
            file: self.origin.clone(),
            line: locate::line_of_path(&self.source, path),
            key: Some(locate::dotted(path)),
            message: message.into(),
        }
    }

    /// Checks everything that can be checked without reading meshes.
    fn validate(&self) -> Result<(), SceneError> {
        let s = &self.spec;
        if !is_name(&s.scene.name) {
            return Err(self.error_at(
                &[Seg::Key("scene"), Seg::Key("name")],
                "a scene name must be non-empty and use only letters, digits, '-' and '_' (it names output folders)",
            ));
        }
        if s.organs.is_empty() {
            return Err(self.error_at(&[Seg::Key("organs")], "a scene needs at least one [[organs]] entry"));
        }
        for i in 0..s.organs.len() {
            self.validate_organ(i)?;
        }
        self.validate_tools()?;
        if s.effects.cutting && !s.tools.iter().any(|t| matches!(t, ToolSpec::Scalpel { .. })) {
            return Err(self.error_at(
                &[Seg::Key("effects"), Seg::Key("cutting")],
                "cutting is enabled but the scene has no scalpel tool; add a [[tools]] entry with kind = \"scalpel\"",
            ));
        }
        let marked: Vec<usize> = (0..s.organs.len()).filter(|&i| s.organs[i].cuttable).collect();
        if let Some(&i) = marked.get(1).or(marked.first().filter(|_| !s.effects.cutting)) {
            return Err(self.error_at(
                &organ_key(i, &[Seg::Key("cuttable")]),
                if s.effects.cutting {
                    format!(
                        "organ '{}' is marked cuttable, but so is organ '{}': the scalpel cuts one organ",
                        s.organs[i].name, s.organs[marked[0]].name
                    )
                } else {
                    "the organ is marked cuttable, but cutting is off: set [effects] cutting = true".to_string()
                },
            ));
        }
        if let Some(&i) = marked.first()
            && s.organs[i].materials.iter().any(|m| m.damage.is_some())
        {
            return Err(self.error_at(
                &organ_key(i, &[Seg::Key("cuttable")]),
                format!(
                    "organ '{}' tears (a material with a damage law), and cutting and tearing are not composed on one organ in this version: mark another organ cuttable",
                    s.organs[i].name
                ),
            ));
        }
        if s.effects.cutting && self.cut_organ().is_none() {
            return Err(self.error_at(
                &[Seg::Key("effects"), Seg::Key("cutting")],
                "cutting is enabled but every organ tears (a damage law): cutting acts on the first organ that does not (cutting and tearing are not composed on one organ in this version)",
            ));
        }
        if s.fidelity.cutting == schema::CuttingModel::CorotationalXfem && !s.effects.cutting {
            return Err(self.error_at(
                &[Seg::Key("fidelity"), Seg::Key("cutting")],
                "fidelity.cutting = \"corotational_xfem\" chooses a cutting model, but cutting is off: set effects.cutting = true",
            ));
        }
        if s.fidelity.cutting == schema::CuttingModel::CorotationalXfem
            && let Some(i) = self.cut_organ().filter(|&i| self.organ_large(i))
        {
            return Err(self.error_at(
                &[Seg::Key("fidelity"), Seg::Key("cutting")],
                format!(
                    "the cut organ '{}' deforms largely, and the co-rotational cutting model is not composed with the large-deformation law in this version: use fidelity.cutting = \"pgd_xfem\" (the cut's force scaled by the lattice), or give the organ deformation = \"linear\"",
                    s.organs[i].name
                ),
            ));
        }
        self.validate_visuals()?;
        if s.effects.tearing && !s.tools.iter().any(|t| matches!(t, ToolSpec::Grasper { .. })) {
            return Err(self.error_at(
                &[Seg::Key("effects"), Seg::Key("tearing")],
                "tearing is enabled but the scene has no grasper tool; add a [[tools]] entry with kind = \"grasper\"",
            ));
        }
        self.validate_tearing()?;
        self.validate_reduced_settings()?;
        self.validate_meshless()
    }

    /// Organ `i`: its name (unique), density, mesh settings, materials, accessible region,
    /// supports and loads, each checked without reading its mesh.
    fn validate_organ(&self, i: usize) -> Result<(), SceneError> {
        let (s, o) = (&self.spec, &self.spec.organs[i]);
        let at = |rest: &[Seg<'static>]| organ_key(i, rest);
        if !is_name(&o.name) {
            return Err(self.error_at(
                &at(&[Seg::Key("name")]),
                "an organ name must be non-empty and use only letters, digits, '-' and '_'",
            ));
        }
        if s.organs[..i].iter().any(|p| p.name == o.name) {
            return Err(self.error_at(&at(&[Seg::Key("name")]), format!("organ name '{}' is used twice", o.name)));
        }
        if let Err(e) = material::validate_density(o.density) {
            return Err(self.error_at(&at(&[Seg::Key("density")]), e.to_string()));
        }
        self.validate_mesh_spec(&o.mesh, &at(&[Seg::Key("mesh")]))?;
        if o.materials.is_empty() {
            return Err(self.error_at(
                &at(&[Seg::Key("materials")]),
                "an organ needs at least one [[organs.materials]] entry",
            ));
        }
        for (m, spec) in o.materials.iter().enumerate() {
            self.validate_material(spec, &at(&[Seg::Key("materials"), Seg::Index(m)]))?;
        }
        if let Err(e) = o.accessible.validate() {
            return Err(self.error_at(&at(&[Seg::Key("accessible")]), e.to_string()));
        }
        let supports = o.fixed.supports();
        if supports.is_empty() {
            return Err(self.error_at(&at(&[Seg::Key("fixed")]), "an organ needs at least one support"));
        }
        for (k, sup) in supports.iter().enumerate() {
            let key = match o.fixed {
                FixedSpec::Region(_) => at(&[Seg::Key("fixed")]),
                FixedSpec::Supports(_) => at(&[Seg::Key("fixed"), Seg::Index(k)]),
            };
            if let Err(e) = sup.region.validate() {
                return Err(self.error_at(&key, e.to_string()));
            }
            if sup.components.as_ref().is_some_and(|c| c.is_empty()) {
                return Err(self.error_at(&key, "`components` must name at least one of \"x\", \"y\", \"z\""));
            }
            if sup.stiffness.is_some_and(|k| !(k.is_finite() && k > 0.0)) {
                return Err(self.error_at(&key, "`stiffness` must be positive (Pa/m: springs per unit area)"));
            }
        }
        for (l, load) in o.loads.iter().enumerate() {
            let p = at(&[Seg::Key("loads"), Seg::Index(l)]);
            let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
            let bad = match load {
                LoadSpec::Point { at, force } => (!finite(at) || !finite(force)).then_some("point loads need finite `at` and `force`"),
                LoadSpec::Force { region, force, .. } => region
                    .validate()
                    .err()
                    .map(|_| "invalid region")
                    .or((!finite(force)).then_some("`force` must be finite")),
                LoadSpec::Traction { region, traction } => region
                    .validate()
                    .err()
                    .map(|_| "invalid region")
                    .or((!finite(traction)).then_some("`traction` must be finite")),
                LoadSpec::Pressure { region, pressure } => region
                    .validate()
                    .err()
                    .map(|_| "invalid region")
                    .or((!pressure.is_finite()).then_some("`pressure` must be finite (Pa)")),
                LoadSpec::Gravity { acceleration } => (!finite(acceleration)).then_some("`acceleration` must be finite"),
                LoadSpec::Displacement { region, x, y, z, .. } => {
                    if region.validate().is_err() {
                        Some("invalid region")
                    } else if x.is_none() && y.is_none() && z.is_none() {
                        Some("a displacement load must prescribe at least one of x, y, z")
                    } else if [x, y, z].iter().any(|c| c.is_some_and(|v| !v.is_finite())) {
                        Some("prescribed displacements must be finite")
                    } else {
                        None
                    }
                }
            };
            if let Some(msg) = bad {
                return Err(self.error_at(&p, msg));
            }
        }
        Ok(())
    }

    /// The tools: at most [`schema::MAX_TOOLS`], unique names, positive dimensions
    /// and forces within the global limit.
    fn validate_tools(&self) -> Result<(), SceneError> {
        let s = &self.spec;
        if s.tools.len() > schema::MAX_TOOLS {
            return Err(self.error_at(
                &[Seg::Key("tools")],
                format!(
                    "the scene names {} tools; a session moves at most {} at once",
                    s.tools.len(),
                    schema::MAX_TOOLS
                ),
            ));
        }
        let mut seen = Vec::new();
        for (t, tool) in s.tools.iter().enumerate() {
            let at = [Seg::Key("tools"), Seg::Index(t)];
            if seen.contains(&tool.name()) {
                return Err(self.error_at(&at, format!("tool name '{}' is used twice", tool.name())));
            }
            seen.push(tool.name());
            let positive = |v: f64| v.is_finite() && v > 0.0;
            let ok = match tool {
                ToolSpec::Probe { radius, max_force, .. } => {
                    positive(*radius) && positive(*max_force) && *max_force <= schema::GLOBAL_FORCE_LIMIT_N
                }
                ToolSpec::Scalpel {
                    blade_length,
                    cut_force,
                    max_force,
                    ..
                } => positive(*blade_length) && positive(*cut_force) && positive(*max_force) && *max_force <= schema::GLOBAL_FORCE_LIMIT_N,
                ToolSpec::Grasper { jaw_width, max_force, .. } => positive(*jaw_width) && positive(*max_force),
            };
            if !ok {
                return Err(self.error_at(
                    &at,
                    "tool dimensions and forces must be positive numbers (a probe's or a scalpel's max_force at most 100 N)",
                ));
            }
        }
        Ok(())
    }

    /// The organs' visual meshes: drawn by co-rotational cutting only, Wavefront `.obj`, a
    /// positive scale.
    fn validate_visuals(&self) -> Result<(), SceneError> {
        let s = &self.spec;
        for (i, o) in s.organs.iter().enumerate() {
            let Some(v) = &o.visual else { continue };
            let at = [Seg::Key("organs"), Seg::Index(i), Seg::Key("visual")];
            if s.fidelity.cutting != schema::CuttingModel::CorotationalXfem {
                return Err(self.error_at(
                    &at,
                    "a visual mesh is drawn by co-rotational cutting sessions: set effects.cutting = true and fidelity.cutting = \"corotational_xfem\", or remove [organs.visual]",
                ));
            }
            if self.cut_organ() != Some(i) {
                return Err(self.error_at(
                    &at,
                    "a visual mesh is drawn for the cut organ only: the organ marked cuttable, or the first without a damage law, a linear one first",
                ));
            }
            if !v.file.to_ascii_lowercase().ends_with(".obj") {
                return Err(self.error_at(&at, format!("'{}': visual meshes are read from Wavefront .obj files", v.file)));
            }
            if v.scale.is_some_and(|k| !(k.is_finite() && k > 0.0)) {
                return Err(self.error_at(&at, "`scale` must be a positive number"));
            }
        }
        Ok(())
    }

    /// `[fidelity.pgd]` and `[fidelity.large]`: tolerances in (0, 1), counts at least 1 and
    /// at most what a build may take, the ANM order in range, a positive force.
    fn validate_reduced_settings(&self) -> Result<(), SceneError> {
        let s = &self.spec;
        let p = &s.fidelity.pgd;
        let pgd = [Seg::Key("fidelity"), Seg::Key("pgd")];
        let in_unit = |t: f64| t > 0.0 && t < 1.0;
        if !in_unit(p.tolerance) || !in_unit(p.global_tolerance) || !in_unit(p.enrichment_tolerance) {
            return Err(self.error_at(&pgd, "PGD tolerances must lie in (0, 1)"));
        }
        if p.max_modes == 0 || p.max_iterations == 0 || p.block == 0 {
            return Err(self.error_at(&pgd, "max_modes, max_iterations and block must be at least 1"));
        }
        for (key, value, most) in [
            ("max_modes", p.max_modes, MAX_PGD_MODES),
            ("max_iterations", p.max_iterations, MAX_PGD_ITERATIONS),
            ("block", p.block, MAX_PGD_BLOCK),
        ] {
            if value > most {
                return Err(self.error_at(
                    &[Seg::Key("fidelity"), Seg::Key("pgd"), Seg::Key(key)],
                    format!("{key} = {value} is more than the {most} a build may take (docs/scene.md)"),
                ));
            }
        }
        let l = &s.fidelity.large;
        let large = |k: &'static str| [Seg::Key("fidelity"), Seg::Key("large"), Seg::Key(k)];
        if !(1..=crate::rom::anm::MAX_ORDER).contains(&l.order) {
            return Err(self.error_at(
                &large("order"),
                format!("the ANM order must lie in 1…{}", crate::rom::anm::MAX_ORDER),
            ));
        }
        if l.positions == 0 || l.load_steps == 0 || l.modes == 0 {
            return Err(self.error_at(
                &[Seg::Key("fidelity"), Seg::Key("large")],
                "positions, load_steps and modes must be at least 1",
            ));
        }
        if !(l.max_force.is_finite() && l.max_force > 0.0) {
            return Err(self.error_at(&large("max_force"), "max_force must be a positive force (N)"));
        }
        Ok(())
    }

    /// Tearable materials against `effects.tearing`, and `[fidelity.tearing]`.
    fn validate_tearing(&self) -> Result<(), SceneError> {
        let s = &self.spec;
        let tearable = s.organs.iter().any(|o| o.materials.iter().any(|m| m.damage.is_some()));
        if s.effects.tearing && !tearable {
            return Err(self.error_at(
                &[Seg::Key("effects"), Seg::Key("tearing")],
                "tearing is enabled but no material can tear; mark one with damage = { alpha = …, beta = … } (or law = \"softening\", strength, fracture_energy)",
            ));
        }
        if !s.effects.tearing
            && let Some((i, m)) = s
                .organs
                .iter()
                .enumerate()
                .find_map(|(i, o)| o.materials.iter().position(|m| m.damage.is_some()).map(|m| (i, m)))
        {
            return Err(self.error_at(
                &[
                    Seg::Key("organs"),
                    Seg::Index(i),
                    Seg::Key("materials"),
                    Seg::Index(m),
                    Seg::Key("damage"),
                ],
                "this material can tear but effects.tearing is false: set [effects] tearing = true, or remove `damage`",
            ));
        }
        if s.effects.tearing
            && let Some(i) = tearing::tearable_organ(self)
            && self.organ_large(i)
        {
            let at = if s.organs[i].deformation.is_some() {
                organ_key(i, &[Seg::Key("deformation")])
            } else {
                vec![Seg::Key("effects"), Seg::Key("deformation")]
            };
            return Err(self.error_at(
                &at,
                format!(
                    "organ '{}' tears, and tearing with large deformations on one organ is not composed in this version: give it deformation = \"linear\" (another organ may still deform largely)",
                    s.organs[i].name
                ),
            ));
        }
        let t = &s.fidelity.tearing;
        let key = |k: &'static str| [Seg::Key("fidelity"), Seg::Key("tearing"), Seg::Key(k)];
        let steps = t
            .schedule
            .iter()
            .try_fold(0usize, |n, b| n.checked_add(b.steps))
            .unwrap_or(usize::MAX);
        if t.schedule.iter().any(|b| !b.scale.is_finite()) || steps == 0 || steps > 100_000 {
            return Err(self.error_at(&key("schedule"), "the schedule needs 1 to 100000 steps in all, with finite scales"));
        }
        if t.pod_vectors.is_some_and(|n| n == 0 || n > 20) {
            return Err(self.error_at(&key("pod_vectors"), "pod_vectors must be between 1 and 20"));
        }
        if !(t.pod_energy > 0.0 && t.pod_energy <= 1.0) {
            return Err(self.error_at(&key("pod_energy"), "pod_energy must lie in (0, 1]"));
        }
        if !(t.margin >= 0.0 && t.margin <= 10.0) {
            return Err(self.error_at(&key("margin"), "margin must lie in [0, 10]"));
        }
        if !(2..=100_000).contains(&t.grid) {
            return Err(self.error_at(&key("grid"), "grid must be between 2 and 100000 nodes"));
        }
        if !(t.tolerance > 0.0 && t.tolerance < 1.0) {
            return Err(self.error_at(&key("tolerance"), "tolerance must lie in (0, 1)"));
        }
        if !(1..=1000).contains(&t.max_modes) {
            return Err(self.error_at(&key("max_modes"), "max_modes must be between 1 and 1000"));
        }
        if !(t.max_damage_increment > 0.0 && t.max_damage_increment <= 1.0) {
            return Err(self.error_at(&key("max_damage_increment"), "max_damage_increment must lie in (0, 1]"));
        }
        if !(1..=64).contains(&t.max_substeps) || !t.max_substeps.is_power_of_two() {
            return Err(self.error_at(&key("max_substeps"), "max_substeps must be a power of two from 1 to 64"));
        }
        if !(1..=64).contains(&t.grasp_sites) {
            return Err(self.error_at(&key("grasp_sites"), "grasp_sites must be between 1 (the scene's grasp only) and 64"));
        }
        Ok(())
    }

    /// `[fidelity.meshless]` and the organs' cuts.
    fn validate_meshless(&self) -> Result<(), SceneError> {
        let s = &self.spec;
        let m = &s.fidelity.meshless;
        let key = |k: &'static str| [Seg::Key("fidelity"), Seg::Key("meshless"), Seg::Key(k)];
        if !(m.support.is_finite() && m.support > 1.0 && m.support <= 10.0) {
            return Err(self.error_at(
                &key("support"),
                "the influence radius must lie in (1, 10] mean edge lengths (2.2 is the usual choice)",
            ));
        }
        if !(1..=2).contains(&m.integration) {
            return Err(self.error_at(&key("integration"), "integration must be 1 or 2 points per cell and axis"));
        }
        if !(m.tolerance.is_finite() && m.tolerance > 0.0) {
            return Err(self.error_at(&key("tolerance"), "the tolerance must be a positive length (m)"));
        }
        if m.max_steps == 0 || m.max_steps <= m.loading_steps {
            return Err(self.error_at(&key("max_steps"), "max_steps must exceed loading_steps"));
        }
        let sliver = s.fidelity.xfem.sliver;
        if !(sliver.is_finite() && (0.0..0.5).contains(&sliver)) {
            return Err(self.error_at(
                &[Seg::Key("fidelity"), Seg::Key("xfem"), Seg::Key("sliver")],
                "sliver must be a volume fraction in [0, 0.5) (default 1e-4)",
            ));
        }
        for (o, organ) in s.organs.iter().enumerate() {
            for (c, cut) in organ.cuts.iter().enumerate() {
                let at = [Seg::Key("organs"), Seg::Index(o), Seg::Key("cuts"), Seg::Index(c)];
                if !s.effects.cutting {
                    return Err(self.error_at(&at, "the organ has cuts but cutting is off: set effects.cutting = true"));
                }
                if self.cut_organ() != Some(o) {
                    return Err(self.error_at(
                        &at,
                        "only the cut organ has cuts: the organ marked cuttable, or the first without a damage law, a linear one first (a tearable organ tears and is not cut)",
                    ));
                }
                let hyperelastic = organ.materials.iter().any(|m| m.model != schema::MaterialModel::Linear);
                if hyperelastic && s.fidelity.solver != SolverKind::Meshless {
                    return Err(self.error_at(
                        &at,
                        "cuts in a hyperelastic organ are made by the meshless solver: set fidelity.solver = \"meshless\" (linear organs are cut by XFEM)",
                    ));
                }
                let blade: Vec<([f64; 3], [f64; 3])> = cut.blade.iter().map(|b| (b[0], b[1])).collect();
                if let Err(e) = Cut::swept(&blade) {
                    return Err(self.error_at(&[&at[..], &[Seg::Key("blade")]].concat(), e.to_string()));
                }
            }
        }
        Ok(())
    }

    fn validate_mesh_spec(&self, m: &MeshSpec, at: &[Seg<'_>]) -> Result<(), SceneError> {
        let key = |k: &'static str| -> Vec<Seg<'_>> {
            let mut v = at.to_vec();
            v.push(Seg::Key(k));
            v
        };
        match (&m.file, m.builtin) {
            (Some(_), Some(_)) => return Err(self.error_at(at, "give either `file` or `builtin`, not both")),
            (None, None) => {
                return Err(self.error_at(
                    at,
                    "give a mesh `file` (.msh, .vtu, .vtk) or a `builtin` mesh (\"lobe\", \"block\" or \"dome\")",
                ));
            }
            _ => {}
        }
        let lobe_only = [("semi_axes", m.semi_axes.is_some()), ("bend", m.bend.is_some())];
        let block_only = [
            ("origin", m.origin.is_some()),
            ("size", m.size.is_some()),
            ("cell", m.cell.is_some()),
        ];
        let dome_only = [
            ("curvature_radius", m.curvature_radius.is_some()),
            ("base_radius", m.base_radius.is_some()),
            ("thickness", m.thickness.is_some()),
        ];
        let builtin_only = [("divisions", m.divisions.is_some())];
        let forbid = |list: &[(&'static str, bool)], why: &str| -> Result<(), SceneError> {
            match list.iter().find(|(_, set)| *set) {
                Some((k, _)) => Err(self.error_at(&key(k), format!("`{k}` {why}"))),
                None => Ok(()),
            }
        };
        match m.builtin {
            None => {
                forbid(&lobe_only, "only applies to builtin = \"lobe\"")?;
                forbid(&block_only, "only applies to builtin = \"block\"")?;
                forbid(&dome_only, "only applies to builtin = \"dome\"")?;
                forbid(&builtin_only, "only applies to built-in meshes")?;
            }
            Some(BuiltinMesh::Lobe) => {
                forbid(&block_only, "only applies to builtin = \"block\"")?;
                forbid(&dome_only, "only applies to builtin = \"dome\"")?;
                if m.scale.is_some() {
                    return Err(self.error_at(
                        &key("scale"),
                        "`scale` applies to mesh files; give a built-in lobe its size with `semi_axes` (m)",
                    ));
                }
                if m.semi_axes.is_some_and(|a| a.iter().any(|v| !(v.is_finite() && *v > 0.0))) {
                    return Err(self.error_at(&key("semi_axes"), "semi-axes must be positive lengths (m)"));
                }
                if m.bend.is_some_and(|b| !(b.is_finite() && b.abs() <= 2.0)) {
                    return Err(self.error_at(&key("bend"), "bend must lie in [-2, 2]"));
                }
            }
            Some(BuiltinMesh::Dome) => {
                forbid(&lobe_only, "only applies to builtin = \"lobe\"")?;
                forbid(&block_only, "only applies to builtin = \"block\"")?;
                if m.scale.is_some() {
                    return Err(self.error_at(&key("scale"), "`scale` applies to mesh files; give a built-in dome its radii (m)"));
                }
                let d = procedural::DomeParams::default();
                let (r, a, t) = (
                    m.curvature_radius.unwrap_or(d.curvature_radius),
                    m.base_radius.unwrap_or(d.base_radius),
                    m.thickness.unwrap_or(d.thickness),
                );
                let ok = |v: f64| v.is_finite() && v > 0.0;
                if !(ok(r) && ok(a) && ok(t)) {
                    return Err(self.error_at(
                        at,
                        "the dome's curvature_radius, base_radius and thickness must be positive lengths (m)",
                    ));
                }
                if a >= r || t >= 0.5 * r {
                    return Err(self.error_at(
                        at,
                        "a dome needs base_radius < curvature_radius and a thickness well below the radius of curvature",
                    ));
                }
                if m.divisions.is_some_and(|d| d[0] != d[1]) {
                    return Err(self.error_at(&key("divisions"), "a dome has divisions = [n, n, layers] (the same n both ways)"));
                }
            }
            Some(BuiltinMesh::Block) => {
                forbid(&lobe_only, "only applies to builtin = \"lobe\"")?;
                forbid(&dome_only, "only applies to builtin = \"dome\"")?;
                if m.scale.is_some() {
                    return Err(self.error_at(&key("scale"), "`scale` applies to mesh files; give a built-in block its `size` (m)"));
                }
                if m.size.is_none() {
                    return Err(self.error_at(at, "a built-in block needs `size` (m)"));
                }
                if m.size.is_some_and(|a| a.iter().any(|v| !(v.is_finite() && *v > 0.0))) {
                    return Err(self.error_at(&key("size"), "block edge lengths must be positive (m)"));
                }
                if m.origin.is_some_and(|o| o.iter().any(|v| !v.is_finite())) {
                    return Err(self.error_at(&key("origin"), "origin must be finite"));
                }
            }
        }
        if let Some(d) = m.divisions {
            if d.iter().any(|&n| n == 0 || n > 2000) {
                return Err(self.error_at(&key("divisions"), "divisions must lie in 1..=2000 along each axis"));
            }
            let per_cube = cells_per_division(m);
            let cells = d.iter().product::<usize>().saturating_mul(per_cube);
            if cells > MAX_BUILTIN_CELLS {
                return Err(self.error_at(
                    &key("divisions"),
                    format!(
                        "{cells} cells ({} per division cube) is more than {MAX_BUILTIN_CELLS}; use fewer divisions",
                        per_cube
                    ),
                ));
            }
        }
        if m.scale.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
            return Err(self.error_at(&key("scale"), "scale must be a positive number (e.g. 0.001 for a mesh in mm)"));
        }
        if m.translate.is_some_and(|t| t.iter().any(|v| !v.is_finite())) {
            return Err(self.error_at(&key("translate"), "translate must be finite (m)"));
        }
        Ok(())
    }

    fn validate_material(&self, m: &MaterialSpec, at: &[Seg<'_>]) -> Result<(), SceneError> {
        let key = |k: &'static str| -> Vec<Seg<'_>> {
            let mut v = at.to_vec();
            v.push(Seg::Key(k));
            v
        };
        if m.volumetric.is_some() && !matches!(m.model, MaterialModel::NeoHookean | MaterialModel::MooneyRivlin) {
            return Err(self.error_at(
                &key("volumetric"),
                "`volumetric` chooses U(J) of neo_hookean and mooney_rivlin; linear and stvk materials have none",
            ));
        }
        if let Some(d) = &m.damage {
            self.validate_damage(m, d, &key("damage"))?;
        }
        match m.model {
            MaterialModel::Linear | MaterialModel::Stvk | MaterialModel::NeoHookean => {
                let young = m.young.ok_or_else(|| self.error_at(at, "this model needs `young` (Pa)"))?;
                let poisson = m.poisson.ok_or_else(|| self.error_at(at, "this model needs `poisson`"))?;
                for k in ["c10", "c01", "bulk"] {
                    let set = match k {
                        "c10" => m.c10.is_some(),
                        "c01" => m.c01.is_some(),
                        _ => m.bulk.is_some(),
                    };
                    if set {
                        return Err(self.error_at(&key(k), format!("`{k}` only applies to model = \"mooney_rivlin\"")));
                    }
                }
                if let Err(e) = LinearElastic::new(young, poisson) {
                    let k = if matches!(e, material::MaterialError::Young(_)) {
                        "young"
                    } else {
                        "poisson"
                    };
                    return Err(self.error_at(&key(k), e.to_string()));
                }
            }
            MaterialModel::MooneyRivlin => {
                let (Some(c10), Some(c01), Some(bulk)) = (m.c10, m.c01, m.bulk) else {
                    return Err(self.error_at(at, "mooney_rivlin needs `c10`, `c01` and `bulk` (Pa)"));
                };
                if !(c10 + c01 > 0.0 && bulk > 0.0 && c10.is_finite() && c01.is_finite() && bulk.is_finite()) {
                    return Err(self.error_at(at, "mooney_rivlin needs c10 + c01 > 0 and bulk > 0"));
                }
            }
        }
        Ok(())
    }

    /// A material's `damage = { … }`: the keys of its form, in range.
    fn validate_damage(&self, m: &MaterialSpec, d: &DamageSpec, at: &[Seg<'_>]) -> Result<(), SceneError> {
        let key = |k: &'static str| -> Vec<Seg<'_>> {
            let mut v = at.to_vec();
            v.push(Seg::Key(k));
            v
        };
        if m.model != MaterialModel::Linear {
            return Err(self.error_at(
                at,
                "damage applies to model = \"linear\" materials (seed 000 chapter 4 is small-strain)",
            ));
        }
        let (needs, foreign): (&[(&str, Option<f64>)], &[(&str, Option<f64>)]) = match d.law {
            DamageForm::Simo => (
                &[("alpha", d.alpha), ("beta", d.beta)],
                &[("strength", d.strength), ("fracture_energy", d.fracture_energy)],
            ),
            DamageForm::Softening => (
                &[("strength", d.strength), ("fracture_energy", d.fracture_energy)],
                &[("alpha", d.alpha), ("beta", d.beta)],
            ),
        };
        let form = if d.law == DamageForm::Simo { "simo" } else { "softening" };
        if let Some((k, _)) = needs.iter().find(|(_, v)| v.is_none()) {
            return Err(self.error_at(at, format!("law = \"{form}\" needs `{k}`")));
        }
        if let Some((k, _)) = foreign.iter().find(|(_, v)| v.is_some()) {
            return Err(self.error_at(&key(k), format!("`{k}` does not apply to law = \"{form}\"")));
        }
        let checked = match d.law {
            DamageForm::Simo => DamageLaw::simo(d.alpha.unwrap_or(0.0), d.beta.unwrap_or(0.0), d.residual).map(|_| ()),
            // the cell-size limit is checked per cell when the model is built
            DamageForm::Softening => DamageLaw::softening(
                m.young.unwrap_or(1.0),
                d.strength.unwrap_or(0.0),
                d.fracture_energy.unwrap_or(0.0),
                0.0,
                d.residual,
            )
            .map(|_| ())
            .or_else(|e| {
                if matches!(e, LawError::CellTooLarge { .. }) {
                    Ok(())
                } else {
                    Err(e)
                }
            }),
        };
        if let Err(LawError::Range { key: k, .. }) = &checked {
            let k: &'static str = k;
            return Err(self.error_at(&key(k), checked.unwrap_err().to_string()));
        }
        if !(d.torn > 0.0 && d.torn <= 1.0) {
            return Err(self.error_at(&key("torn"), format!("torn = {} must lie in (0, 1]", d.torn)));
        }
        Ok(())
    }

    /// A material entry's small-strain moduli and, for a hyperelastic model, its law.
    fn material_laws(&self, spec: &MaterialSpec, at: &[Seg<'_>]) -> Result<(LinearElastic, Option<Hyperelastic>), SceneError> {
        let linear = |young: Option<f64>, poisson: Option<f64>| {
            LinearElastic::new(young.unwrap_or(0.0), poisson.unwrap_or(0.0)).map_err(|e| self.error_at(at, e.to_string()))
        };
        let vol = spec.volumetric.unwrap_or_default();
        Ok(match spec.model {
            MaterialModel::Linear => (linear(spec.young, spec.poisson)?, None),
            MaterialModel::Stvk => {
                let m = linear(spec.young, spec.poisson)?;
                (m, Some(Hyperelastic::svk(&m)))
            }
            MaterialModel::NeoHookean => {
                let m = linear(spec.young, spec.poisson)?;
                (m, Some(Hyperelastic::neo_hookean(&m).with_volumetric(vol)))
            }
            MaterialModel::MooneyRivlin => {
                let (c10, c01, kappa) = (spec.c10.unwrap_or(0.0), spec.c01.unwrap_or(0.0), spec.bulk.unwrap_or(0.0));
                // small-strain moduli: μ = 2 (C₁₀ + C₀₁), ν from K and μ
                let mu = 2.0 * (c10 + c01);
                let nu = (3.0 * kappa - 2.0 * mu) / (2.0 * (3.0 * kappa + mu));
                (
                    linear(Some(2.0 * mu * (1.0 + nu)), Some(nu))?,
                    Some(Hyperelastic::MooneyRivlin {
                        c10,
                        c01,
                        kappa,
                        volumetric: vol,
                    }),
                )
            }
        })
    }

    /// Resolves a mesh path relative to the scene file's folder. A built-in scene's relative
    /// path is looked up, in order: for a path into `../shared/`, in the folder
    /// `VADEMECUM_SHARED` names; from the working folder and each folder above it (so that
    /// `../shared/data/…` is found from the repository or any folder inside it); beside the
    /// checkout this library was built from. Where none holds it, the path as written (and
    /// the error reading it says what to set).
    pub fn resolve_path(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            return p.to_path_buf();
        }
        match self.origin.parent() {
            Some(dir) if !self.is_builtin() => dir.join(p),
            _ => {
                let in_shared = p.strip_prefix(SHARED_PREFIX).ok();
                let from_env = in_shared
                    .zip(std::env::var_os(SHARED_ENV))
                    .map(|(rest, dir)| Path::new(&dir).join(rest));
                let from_cwd = || {
                    std::env::current_dir()
                        .ok()
                        .and_then(|cwd| cwd.ancestors().map(|d| d.join(p)).find(|c| c.exists()))
                };
                let beside_checkout = || {
                    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
                    Some(repo.join(p)).filter(|c| c.exists())
                };
                from_env
                    .filter(|c| c.exists())
                    .or_else(from_cwd)
                    .or_else(beside_checkout)
                    .unwrap_or_else(|| p.to_path_buf())
            }
        }
    }

    /// Whether the scene is one of the built-ins (compiled into the binary).
    pub fn is_builtin(&self) -> bool {
        self.origin.to_string_lossy().starts_with("<builtin")
    }

    /// For a built-in scene reading `path` from the shared data, what to set when it is not
    /// found; empty otherwise.
    fn builtin_data_hint(&self, path: &str) -> String {
        if self.is_builtin() && Path::new(path).starts_with(SHARED_PREFIX) && !self.resolve_path(path).exists() {
            format!(
                " (this built-in scene reads the shared data: set {SHARED_ENV} to the folder that holds data/meshes, or run from the repository's folder)"
            )
        } else {
            String::new()
        }
    }

    /// Builds organ `index`'s mesh (read or generated, scaled, checked; nodes no cell uses
    /// dropped).
    pub fn organ_mesh(&self, index: usize) -> Result<Mesh, SceneError> {
        self.organ_mesh_noted(index).map(|(mesh, _)| mesh)
    }

    /// [`Scene::organ_mesh`], with what was done to the mesh file that the user should know.
    fn organ_mesh_noted(&self, index: usize) -> Result<(Mesh, Vec<String>), SceneError> {
        let mut notes = Vec::new();
        let o = &self.spec.organs[index];
        let at = [Seg::Key("organs"), Seg::Index(index), Seg::Key("mesh")];
        let m = &o.mesh;
        let mut mesh = match (&m.file, m.builtin) {
            (Some(f), _) => {
                let path = self.resolve_path(f);
                let mut mesh = mesh::read(&path).map_err(|e| {
                    self.error_at(
                        &[Seg::Key("organs"), Seg::Index(index), Seg::Key("mesh"), Seg::Key("file")],
                        format!("{e}{}", self.builtin_data_hint(f)),
                    )
                })?;
                mesh.scale(m.scale.unwrap_or(1.0));
                let unused = mesh.drop_unused_nodes();
                if unused > 0 {
                    notes.push(format!(
                        "{unused} node(s) of {f} belong to no cell and were dropped (the remaining {} are renumbered in order)",
                        mesh.n_nodes()
                    ));
                }
                mesh
            }
            (None, Some(BuiltinMesh::Lobe)) => {
                let d = procedural::LobeParams::default();
                let p = procedural::LobeParams {
                    semi_axes: m.semi_axes.unwrap_or(d.semi_axes),
                    bend: m.bend.unwrap_or(d.bend),
                    divisions: m.divisions.unwrap_or(d.divisions),
                };
                let mut mesh = procedural::lobe(&p);
                mesh.check_cells()
                    .map_err(|e| self.error_at(&at, format!("the lobe parameters give a bad mesh: {e}")))?;
                mesh
            }
            (None, Some(BuiltinMesh::Dome)) => {
                let d = procedural::DomeParams::default();
                let mut mesh = procedural::dome(&procedural::DomeParams {
                    curvature_radius: m.curvature_radius.unwrap_or(d.curvature_radius),
                    base_radius: m.base_radius.unwrap_or(d.base_radius),
                    thickness: m.thickness.unwrap_or(d.thickness),
                    divisions: m.divisions.unwrap_or(d.divisions),
                });
                mesh.check_cells()
                    .map_err(|e| self.error_at(&at, format!("the dome parameters give a bad mesh: {e}")))?;
                mesh
            }
            (None, Some(BuiltinMesh::Block)) => {
                let size = m.size.unwrap_or([1.0; 3]);
                let div = m.divisions.unwrap_or(DEFAULT_BLOCK_DIVISIONS);
                let origin = m.origin.unwrap_or([0.0; 3]);
                match m.cell.unwrap_or(CellKind::Hex8) {
                    CellKind::Hex8 => procedural::block_hex(origin, size, div),
                    CellKind::Tet4 => procedural::block_tet(origin, size, div),
                }
            }
            (None, None) => unreachable!("validated: file or builtin"),
        };
        if let Some(t) = m.translate {
            mesh.translate(t);
        }
        Ok((mesh, notes))
    }

    /// Builds everything organ `index` needs for a static solve.
    pub fn organ_model(&self, index: usize) -> Result<OrganModel, SceneError> {
        self.organ_model_within(index, None)
    }

    /// [`Scene::organ_model`], refusing — before anything is assembled — a mesh whose direct
    /// solve would need more than `max_memory` bytes ([`crate::solve::memory`]).
    pub fn organ_model_within(&self, index: usize, max_memory: Option<u64>) -> Result<OrganModel, SceneError> {
        let (mesh, notes) = self.organ_mesh_noted(index)?;
        if let Some(limit) = max_memory {
            // the wide stencil unless the scene names another treatment (conservative)
            let wide = mesh.kind == CellKind::Tet4 && matches!(self.spec.fidelity.locking, None | Some(Locking::Nodal));
            crate::solve::memory::check(&mesh, wide, limit)
                .map_err(|m| self.error_at(&[Seg::Key("organs"), Seg::Index(index), Seg::Key("mesh")], m.to_string()))?;
        }
        let mut model = self.organ_model_with_mesh(index, mesh)?;
        let name = &self.spec.organs[index].name;
        model
            .warnings
            .splice(0..0, notes.into_iter().map(|n| format!("organ '{name}': {n}")));
        Ok(model)
    }

    /// Organ `index`'s visual mesh (`[organs.visual]`), read and placed as its simulation
    /// mesh is (the mesh's `scale` unless the visual names its own, then the mesh's
    /// `translate`) and checked to be a closed, consistently oriented surface; `None` when the
    /// organ has none.
    pub fn organ_visual(&self, index: usize) -> Result<Option<crate::xfem::visual::VisualMesh>, SceneError> {
        let o = &self.spec.organs[index];
        let Some(v) = &o.visual else { return Ok(None) };
        let at = [Seg::Key("organs"), Seg::Index(index), Seg::Key("visual")];
        let scale = v.scale.or(o.mesh.scale).unwrap_or(1.0);
        let mut visual = crate::xfem::visual::VisualMesh::load_obj(&self.resolve_path(&v.file), scale)
            .map_err(|e| self.error_at(&at, format!("{e}{}", self.builtin_data_hint(&v.file))))?;
        if let Some(t) = o.mesh.translate {
            for p in &mut visual.vertices {
                for k in 0..3 {
                    p[k] += t[k];
                }
            }
        }
        if let Some(p) = visual.vertices.iter().find(|p| p.iter().any(|x| x.abs() > MAX_VISUAL_COORDINATE_M)) {
            return Err(self.error_at(
                &at,
                format!(
                    "'{}' scaled by {scale} has a vertex at {p:?} m, farther than {MAX_VISUAL_COORDINATE_M} m from the origin: no organ is that large (check `scale`)",
                    v.file
                ),
            ));
        }
        let edges = visual.edges();
        if !edges.is_closed_manifold() {
            return Err(self.error_at(
                &at,
                format!(
                    "'{}' is not a closed, consistently oriented surface ({} boundary, {} non-manifold, {} misoriented edges): it cannot be split along a cut",
                    v.file, edges.boundary, edges.non_manifold, edges.misoriented
                ),
            ));
        }
        Ok(Some(visual))
    }

    /// Organ `index`'s deformation model: its own `deformation`, or the scene's
    /// `effects.deformation`.
    pub fn organ_deformation(&self, index: usize) -> schema::DeformationModel {
        let s = &self.spec;
        s.organs[index].deformation.unwrap_or(s.effects.deformation)
    }

    /// Whether organ `index` deforms largely ([`Scene::organ_deformation`]): its bundle
    /// carries an ANM-POD lattice and its palpation force is scaled by it.
    pub fn organ_large(&self, index: usize) -> bool {
        self.organ_deformation(index) == schema::DeformationModel::Large
    }

    /// Whether any organ deforms largely.
    pub fn any_large(&self) -> bool {
        (0..self.spec.organs.len()).any(|i| self.organ_large(i))
    }

    /// The organ a cutting scene cuts (`effects.cutting`): the organ marked `cuttable`, or
    /// the first organ that neither tears (a material with a damage law) nor deforms
    /// largely, or else the first that does not tear — an organ cut and deformed largely at once (the cut's force scaled by the
    /// lattice's stiffening: [`crate::pipeline::cutting::stiffened_cut`]). So in a scene that
    /// retracts one organ, tears a second and cuts a third — the gallbladder, the fat of
    /// Calot's triangle and the cystic duct — each effect knows its organ, and a scene of one
    /// organ that deforms largely cuts it. `None` when the scene does not cut, or every organ
    /// tears (scene validation refuses that).
    pub fn cut_organ(&self) -> Option<usize> {
        if !self.spec.effects.cutting {
            return None;
        }
        if let Some(i) = self.spec.organs.iter().position(|o| o.cuttable) {
            return Some(i);
        }
        let untorn = |i: &usize| self.spec.organs[*i].materials.iter().all(|m| m.damage.is_none());
        let mut organs = (0..self.spec.organs.len()).filter(untorn);
        organs.clone().find(|&i| !self.organ_large(i)).or_else(|| organs.next())
    }

    /// The cut organ's pre-planned cuts ([`Scene::cut_organ`]); none in a scene that does not
    /// cut (scene validation refuses cuts anywhere else).
    pub fn planned_cuts(&self) -> Result<Vec<Cut>, SceneError> {
        self.cut_organ().map_or(Ok(Vec::new()), |o| self.organ_cuts(o))
    }

    /// Organ `index`'s pre-planned cuts (validated when the scene was read).
    pub fn organ_cuts(&self, index: usize) -> Result<Vec<Cut>, SceneError> {
        self.spec.organs[index]
            .cuts
            .iter()
            .enumerate()
            .map(|(c, cut)| {
                let blade: Vec<([f64; 3], [f64; 3])> = cut.blade.iter().map(|b| (b[0], b[1])).collect();
                Cut::swept(&blade).map_err(|e| {
                    self.error_at(
                        &[Seg::Key("organs"), Seg::Index(index), Seg::Key("cuts"), Seg::Index(c)],
                        e.to_string(),
                    )
                })
            })
            .collect()
    }

    /// Like [`Scene::organ_model`], with a mesh already built (e.g. to reuse it).
    pub fn organ_model_with_mesh(&self, index: usize, mesh: Mesh) -> Result<OrganModel, SceneError> {
        let o = &self.spec.organs[index];
        let base = |rest: &[Seg<'static>]| organ_key(index, rest);
        let (materials, laws) = self.organ_materials(index, &mesh)?;

        let (locking, warnings) = resolve_locking(self.spec.fidelity.locking, mesh.kind, &materials, laws.as_ref())
            .map_err(|m| self.error_at(&[Seg::Key("fidelity"), Seg::Key("locking")], format!("organ '{}': {m}", o.name)))?;
        let warnings = warnings.into_iter().map(|w| format!("organ '{}': {w}", o.name)).collect();

        let boundary = Boundary::of(&mesh);
        let mut problem = StaticProblem::new(mesh.n_nodes());
        let mut named_regions = self.organ_supports(index, &mesh, &boundary, &mut problem)?;
        let accessible_nodes = o
            .accessible
            .surface_nodes(&mesh, &boundary)
            .map_err(|e| self.error_at(&base(&[Seg::Key("accessible")]), e.to_string()))?;
        if accessible_nodes.is_empty() {
            return Err(self.error_at(
                &base(&[Seg::Key("accessible")]),
                "the accessible region contains no surface node; tools could touch nothing",
            ));
        }
        self.organ_loads(index, &mesh, &boundary, &materials, &mut problem, &mut named_regions)?;
        Ok(OrganModel {
            name: o.name.clone(),
            mesh,
            materials,
            laws,
            locking,
            warnings,
            problem,
            named_regions,
            accessible_nodes,
            boundary,
        })
    }

    /// Organ `index`'s materials on `mesh`: each cell's (later entries override earlier ones
    /// on the cells they cover), and the hyperelastic laws when the materials are hyperelastic.
    fn organ_materials(&self, index: usize, mesh: &Mesh) -> Result<(MaterialMap, Option<LawMap>), SceneError> {
        let o = &self.spec.organs[index];
        let base = |rest: &[Seg<'static>]| organ_key(index, rest);
        // Materials: later entries override earlier ones on the cells they cover.
        let mut of_cell: Vec<Option<u16>> = vec![None; mesh.n_cells()];
        let mut table = Vec::new();
        let mut laws = Vec::new();
        let mut index_of_first_law: Option<bool> = None;
        for (m, spec) in o.materials.iter().enumerate() {
            let at = base(&[Seg::Key("materials"), Seg::Index(m)]);
            let (mat, law) = self.material_laws(spec, &at)?;
            if index_of_first_law.is_none() {
                index_of_first_law = Some(law.is_some());
            }
            if index_of_first_law != Some(law.is_some()) {
                return Err(self.error_at(
                    &[at.clone(), vec![Seg::Key("model")]].concat(),
                    "an organ's materials must be all linear or all hyperelastic (stvk, neo_hookean, mooney_rivlin)",
                ));
            }
            laws.extend(law);
            table.push(mat);
            let idx = (table.len() - 1) as u16;
            let all = matches!(&spec.region, GroupRef::Name(n) if n == "all");
            let inside: Option<Vec<bool>> = match &spec.within {
                None => None,
                Some(r) => {
                    let nodes = r
                        .nodes(mesh)
                        .map_err(|e| self.error_at(&[at.clone(), vec![Seg::Key("within")]].concat(), e.to_string()))?;
                    let mut node_in = vec![false; mesh.n_nodes()];
                    nodes.iter().for_each(|&n| node_in[n] = true);
                    let cells: Vec<bool> = mesh.cells_iter().map(|c| c.iter().all(|&n| node_in[n])).collect();
                    if !cells.iter().any(|&b| b) {
                        return Err(self.error_at(
                            &[at.clone(), vec![Seg::Key("within")]].concat(),
                            "no cell has all its nodes in this region, so the material covers nothing",
                        ));
                    }
                    Some(cells)
                }
            };
            let covers = |c: usize| inside.as_ref().is_none_or(|v| v[c]);
            if all {
                of_cell
                    .iter_mut()
                    .enumerate()
                    .filter(|(c, _)| covers(*c))
                    .for_each(|(_, m)| *m = Some(idx));
            } else {
                let key = match &spec.region {
                    GroupRef::Tag(t) => t.to_string(),
                    GroupRef::Name(n) => n.clone(),
                };
                let tag = mesh.group_tag(&key).ok_or_else(|| {
                    self.error_at(
                        &[at.clone(), vec![Seg::Key("region")]].concat(),
                        format!("the mesh has no physical group {}", spec.region),
                    )
                })?;
                for (c, r) in mesh.cell_region.iter().enumerate() {
                    if *r == tag && covers(c) {
                        of_cell[c] = Some(idx);
                    }
                }
            }
        }
        if let Some(c) = of_cell.iter().position(|m| m.is_none()) {
            return Err(self.error_at(
                &base(&[Seg::Key("materials")]),
                format!(
                    "cell {c} (region {}) has no material; add a material with region = \"all\" or for its group",
                    mesh.cell_region[c]
                ),
            ));
        }
        let of_cell: Vec<u16> = of_cell.into_iter().map(|m| m.unwrap_or(0)).collect();
        let laws = (!laws.is_empty()).then(|| LawMap {
            laws,
            of_cell: of_cell.clone(),
        });
        let materials = MaterialMap {
            density: vec![o.density; table.len()],
            table,
            of_cell,
        };
        Ok((materials, laws))
    }

    /// Organ `index`'s supports on `mesh` into `problem` (fixed components, or elastic
    /// foundations on the region's boundary faces): each support's name and nodes.
    fn organ_supports(
        &self,
        index: usize,
        mesh: &Mesh,
        boundary: &Boundary,
        problem: &mut StaticProblem,
    ) -> Result<Vec<(String, Vec<usize>)>, SceneError> {
        let o = &self.spec.organs[index];
        let base = |rest: &[Seg<'static>]| organ_key(index, rest);
        let mut named_regions = Vec::new();
        for (k, sup) in o.fixed.supports().iter().enumerate() {
            let key = match o.fixed {
                FixedSpec::Region(_) => base(&[Seg::Key("fixed")]),
                FixedSpec::Supports(_) => base(&[Seg::Key("fixed"), Seg::Index(k)]),
            };
            let nodes = sup.region.nodes(mesh).map_err(|e| self.error_at(&key, e.to_string()))?;
            if nodes.is_empty() {
                return Err(self.error_at(
                    &key,
                    format!("the fixed region selects no node of the mesh (bounding box {:?} – {:?}), so the system would be singular; move or enlarge the region", mesh.bounding_box().0, mesh.bounding_box().1),
                ));
            }
            let components: Vec<usize> = sup
                .components
                .as_ref()
                .map_or(vec![0, 1, 2], |c| c.iter().map(|a| a.index()).collect());
            match sup.stiffness {
                None => {
                    for &i in &components {
                        problem.prescribe(&nodes, i, 0.0);
                    }
                }
                Some(k) => {
                    let faces = sup.region.faces(mesh, boundary).map_err(|e| self.error_at(&key, e.to_string()))?;
                    if faces.is_empty() {
                        return Err(self.error_at(&key, "an elastic foundation needs boundary faces inside its region"));
                    }
                    loads::add_foundation(&mut problem.springs, mesh, boundary, &faces, k, &components);
                }
            }
            let name = sup
                .name
                .clone()
                .unwrap_or_else(|| if k == 0 { "fixed".into() } else { format!("fixed{}", k + 1) });
            named_regions.push((name, nodes));
        }
        Ok(named_regions)
    }

    /// Organ `index`'s loads on `mesh` into `problem` (forces, tractions, pressures, gravity,
    /// prescribed displacements — whose regions are added to `named_regions`).
    fn organ_loads(
        &self,
        index: usize,
        mesh: &Mesh,
        boundary: &Boundary,
        materials: &MaterialMap,
        problem: &mut StaticProblem,
        named_regions: &mut Vec<(String, Vec<usize>)>,
    ) -> Result<(), SceneError> {
        let o = &self.spec.organs[index];
        let base = |rest: &[Seg<'static>]| organ_key(index, rest);
        for (l, load) in o.loads.iter().enumerate() {
            let at = base(&[Seg::Key("loads"), Seg::Index(l)]);
            let region_nodes = |r: &Region| {
                r.nodes(mesh)
                    .map_err(|e| self.error_at(&[at.clone(), vec![Seg::Key("region")]].concat(), e.to_string()))
            };
            let empty = |what: &str| {
                self.error_at(
                    &[at.clone(), vec![Seg::Key("region")]].concat(),
                    format!("the region of this {what} selects nothing"),
                )
            };
            match load {
                LoadSpec::Point { at: p, force } => {
                    let n = nearest_node(mesh, *p).ok_or_else(|| self.error_at(&at, "the mesh has no nodes"))?;
                    loads::add_point_force(&mut problem.forces, n, *force);
                }
                LoadSpec::Force {
                    region,
                    force,
                    distribution,
                } => match distribution {
                    ForceDistribution::Equal => {
                        let nodes = region_nodes(region)?;
                        if nodes.is_empty() {
                            return Err(empty("force"));
                        }
                        loads::add_distributed_force(&mut problem.forces, &nodes, *force);
                    }
                    ForceDistribution::Surface => {
                        let faces = region.faces(mesh, boundary).map_err(|e| self.error_at(&at, e.to_string()))?;
                        if faces.is_empty() {
                            return Err(empty("force (no boundary face has all its nodes inside)"));
                        }
                        // a unit traction's nodal shares ∫ N_a dA, and their sum, the area
                        let mut share = vec![0.0; problem.forces.len()];
                        let area = loads::add_traction(&mut share, mesh, boundary, &faces, [1.0, 0.0, 0.0]);
                        for n in 0..mesh.n_nodes() {
                            loads::add_point_force(&mut problem.forces, n, force.map(|f| f * share[3 * n] / area));
                        }
                    }
                    ForceDistribution::Volume => {
                        let nodes = region_nodes(region)?;
                        let inside: std::collections::HashSet<usize> = nodes.into_iter().collect();
                        let cells: Vec<usize> = (0..mesh.n_cells())
                            .filter(|&c| mesh.cell(c).iter().all(|n| inside.contains(n)))
                            .collect();
                        if cells.is_empty() {
                            return Err(empty("force (no cell has all its nodes inside)"));
                        }
                        loads::add_volume_force(&mut problem.forces, mesh, &cells, *force)
                            .map_err(|e| self.error_at(&at, e.to_string()))?;
                    }
                },
                LoadSpec::Traction { region, traction } => {
                    let faces = region.faces(mesh, boundary).map_err(|e| self.error_at(&at, e.to_string()))?;
                    if faces.is_empty() {
                        return Err(empty("traction (no boundary face has all its nodes inside)"));
                    }
                    loads::add_traction(&mut problem.forces, mesh, boundary, &faces, *traction);
                }
                LoadSpec::Pressure { region, pressure } => {
                    let faces = region.faces(mesh, boundary).map_err(|e| self.error_at(&at, e.to_string()))?;
                    if faces.is_empty() {
                        return Err(empty("pressure (no boundary face has all its nodes inside)"));
                    }
                    problem.add_pressure(mesh, loads::PressureLoad::on(boundary, &faces, *pressure));
                }
                LoadSpec::Gravity { acceleration } => {
                    loads::add_body_force(&mut problem.forces, mesh, materials, *acceleration)
                        .map_err(|e| self.error_at(&at, e.to_string()))?;
                }
                LoadSpec::Displacement { name, region, x, y, z } => {
                    let nodes = region_nodes(region)?;
                    if nodes.is_empty() {
                        return Err(empty("displacement"));
                    }
                    for (i, v) in [x, y, z].into_iter().enumerate() {
                        if let Some(v) = v {
                            problem.prescribe(&nodes, i, *v);
                        }
                    }
                    named_regions.push((name.clone(), nodes));
                }
            }
        }
        Ok(())
    }
}

/// Largest coordinate of a placed visual surface (m): a unit mistake (a `scale` of 1000 for
/// 0.001, or 1e300), never an organ; frames carry f32, which overflows long before 1e300.
pub const MAX_VISUAL_COORDINATE_M: f64 = 1e3;

/// Most PGD modes a scene may ask for (`fidelity.pgd.max_modes`): a vademecum never needs
/// more modes than load states, and a million is far beyond any organ's accessible surface.
pub const MAX_PGD_MODES: usize = 1_000_000;

/// Most alternating fixed-point iterations per enrichment (`fidelity.pgd.max_iterations`): the
/// fixed point converges in a handful; past a thousand a build would never end.
pub const MAX_PGD_ITERATIONS: usize = 1000;

/// Most modes enriched together (`fidelity.pgd.block`).
pub const MAX_PGD_BLOCK: usize = 4096;

/// Where the built-in scenes that read real meshes expect the shared data: a path relative
/// to the repository's folder.
pub const SHARED_PREFIX: &str = "../shared";

/// The environment variable naming the shared data folder (the one holding `data/meshes`),
/// for built-in scenes run from outside the repository.
pub const SHARED_ENV: &str = "VADEMECUM_SHARED";

/// The cells a built-in mesh makes per division cube: six tetrahedra for the tetrahedral
/// built-ins, one hexahedron otherwise.
fn cells_per_division(m: &MeshSpec) -> usize {
    match m.builtin {
        Some(BuiltinMesh::Lobe) => 6,
        Some(BuiltinMesh::Block) if m.cell == Some(CellKind::Tet4) => 6,
        _ => 1,
    }
}

/// Most cells a built-in mesh may produce (its memory alone would be gigabytes).
pub const MAX_BUILTIN_CELLS: usize = 20_000_000;

/// Divisions of a `builtin = "block"` mesh that gives none.
pub const DEFAULT_BLOCK_DIVISIONS: [usize; 3] = [4, 4, 4];

impl MeshSpec {
    /// The divisions a procedural mesh is generated with: the given ones, or its generator's
    /// default; `None` for a mesh file.
    pub fn effective_divisions(&self) -> Option<[usize; 3]> {
        if self.file.is_some() {
            return None;
        }
        let default = match self.builtin? {
            BuiltinMesh::Lobe => procedural::LobeParams::default().divisions,
            BuiltinMesh::Dome => procedural::DomeParams::default().divisions,
            BuiltinMesh::Block => DEFAULT_BLOCK_DIVISIONS,
        };
        Some(self.divisions.unwrap_or(default))
    }
}

/// Poisson's ratio above which a plain linear tetrahedron (or a fully integrated hexahedron)
/// is noticeably too stiff: at ν = 0.45 the Lamé cylinder of tetrahedra is 2.4 % stiff at its
/// worst node, at 0.4999 61 % (BENCHMARKS.md, "Locking-free tetrahedra").
pub const LOCKING_POISSON: f64 = 0.45;

/// The locking treatment of an organ: the scene's `asked` one, or the default for its mesh
/// `kind` and materials (`bbar` on hexahedra; on tetrahedra `nodal` when a material's ν
/// exceeds [`LOCKING_POISSON`]), with warnings for the choices that will lock. Refuses
/// `nodal` on hexahedra.
pub fn resolve_locking(
    asked: Option<Locking>,
    kind: CellKind,
    materials: &MaterialMap,
    laws: Option<&LawMap>,
) -> Result<(Locking, Vec<String>), String> {
    let nu = materials.table.iter().map(|m| m.poisson).fold(f64::NEG_INFINITY, f64::max);
    let near_incompressible = nu > LOCKING_POISSON;
    let locking = match (asked, kind) {
        (Some(Locking::Nodal), CellKind::Hex8) => {
            return Err("locking = \"nodal\" applies to tetrahedra; this organ's mesh is hexahedral (use \"bbar\", the default)".into());
        }
        (Some(l), _) => l,
        (None, CellKind::Hex8) => Locking::Bbar,
        (None, CellKind::Tet4) if near_incompressible => Locking::Nodal,
        (None, CellKind::Tet4) => Locking::None,
    };
    let mut warnings = Vec::new();
    let svk = laws.is_some_and(|l| l.laws.iter().any(|law| !law.splits()));
    if near_incompressible {
        if svk {
            warnings.push(format!(
                "St Venant-Kirchhoff does not split into isochoric and volumetric parts, so no locking treatment acts on its large deformations: at ν = {nu} its {} lock (too stiff); use neo_hookean or mooney_rivlin{}",
                if kind == CellKind::Tet4 { "tetrahedra" } else { "hexahedra" },
                if kind == CellKind::Tet4 { " with locking = \"nodal\"" } else { "" }
            ));
        }
        match (kind, locking) {
            (CellKind::Tet4, l) if l != Locking::Nodal => warnings.push(format!(
                "linear tetrahedra at ν = {nu} lock (too stiff: at ν = 0.4999 they miss from a quarter of the displacement of a Lamé cylinder to 97 % of a bending cantilever's) with locking = \"{}\": use \"nodal\" (the default for tetrahedra above ν = {LOCKING_POISSON})",
                locking_name(l)
            )),
            (CellKind::Hex8, Locking::None) => warnings.push(format!(
                "fully integrated hexahedra at ν = {nu} lock (too stiff) with locking = \"none\": use \"bbar\" (the default)"
            )),
            _ => {}
        }
    }
    Ok((locking, warnings))
}

/// Whether `n` can name a scene, an organ or a folder: non-empty, letters, digits, '-' and '_'.
fn is_name(n: &str) -> bool {
    !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// The key path `organs[index]` followed by `rest`.
fn organ_key(index: usize, rest: &[Seg<'static>]) -> Vec<Seg<'static>> {
    let mut v = vec![Seg::Key("organs"), Seg::Index(index)];
    v.extend_from_slice(rest);
    v
}

fn locking_name(l: Locking) -> &'static str {
    match l {
        Locking::None => "none",
        Locking::Sri => "sri",
        Locking::Bbar => "bbar",
        Locking::Nodal => "nodal",
    }
}
