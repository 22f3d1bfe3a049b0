//! A bundle loaded from disk: the runtime form every session uses ([`LoadedBundle`]), read and
//! verified by [`load_bundle`] (format, version, kind, checksums, shapes, consistency) and
//! held against its scene by [`check_matches`]. The bundle is written by
//! [`crate::offline::write_bundle`].

use std::path::Path;
use std::sync::Arc;

use super::{self as bundle, BundleError, Manifest};
use crate::damage::store::TearArrays;
use crate::mesh::Mesh;
use crate::pgd::vademecum::{LocalCompliance, NodeMajorField, Vademecum};
use crate::rom::palpation::{AnmLattice, LatticeArrays};
use crate::scene::Scene;
use crate::xfem::reduced::RitzBasis;

/// The bundle kind written here.
pub const KIND: &str = "pgd-linear";

/// The K-orthonormal Ritz basis of a cutting session with bare enrichment
/// ([`ReducedCut::orthonormal_basis`](crate::xfem::reduced::ReducedCut::orthonormal_basis)), stored so the session does not compute it (minutes
/// for thousands of modes).
#[derive(Debug, Clone, PartialEq)]
pub struct CutBasis {
    /// Which basis.
    pub basis: RitzBasis,
    /// Row-major `n_free × size` (shared with the sessions that use it).
    pub x: Arc<[f64]>,
    /// Its directions.
    pub size: usize,
}

/// A value of a loaded bundle's build report (`manifest.info`) that a session reads and
/// cannot take: the bundle is damaged or was written by another build.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the bundle's {key} {value} is not {expected}; rebuild it with `vademecum build`")]
pub struct InfoError {
    /// What the value is.
    pub key: &'static str,
    /// The value found.
    pub value: String,
    /// What it should be.
    pub expected: &'static str,
}

/// A bundle loaded from disk.
#[derive(Debug, Clone)]
pub struct LoadedBundle {
    /// Its manifest.
    pub manifest: Manifest,
    /// The online vademecum.
    pub vademecum: Vademecum,
    /// Reference node coordinates (m).
    pub nodes: Vec<[f64; 3]>,
    /// Boundary surface triangles (node indices).
    pub surface: Vec<[usize; 3]>,
    /// The large-deformation lattice, when the bundle has one.
    pub anm: Option<AnmLattice>,
    /// The cutting session's Ritz basis, when the bundle has one (version 2, a scene cutting
    /// with bare enrichment).
    pub cut_basis: Option<CutBasis>,
    /// Tearing's offline arrays, when the bundle has them (the tearable organ of a tearing
    /// scene): the scene's grasp, then the other grasp sites; checked against the scene's
    /// model when a session starts.
    pub tear: Vec<Arc<TearArrays>>,
    /// The modes at the surface nodes in node-major f32 (what a session's frames evaluate),
    /// made once for every session of this bundle ([`Self::surface_field`]).
    pub surface_field: std::sync::OnceLock<Arc<NodeMajorField>>,
}

impl LoadedBundle {
    /// The fewest modes whose displacement-field error the build measured at or below `error`
    /// (the sampled error curve of its report, `manifest.info.error_curve`), when fewer than
    /// the bundle holds: the prefix a session's frames fall back to under load. `None` when the
    /// bundle's own modes are already that coarse, or its report has no curve.
    pub fn modes_for_error(&self, error: f64) -> Option<usize> {
        let curve = self.manifest.info.get("error_curve")?.as_array()?;
        curve
            .iter()
            .filter_map(|p| Some((p.get(0)?.as_u64()? as usize, p.get(1)?.as_f64()?)))
            .filter(|&(k, e)| e <= error && k > 0)
            .map(|(k, _)| k)
            .min()
            .filter(|&k| k < self.vademecum.modes())
    }

    /// The displacement-field error the build measured for the vademecum's own modes (the
    /// last point of `manifest.info.error_curve` at or below its mode count): the relative
    /// error of what the modes carry, such as the compliance between two distant contacts.
    /// `None` when the report has no curve.
    pub fn modes_error(&self) -> Option<f64> {
        let curve = self.manifest.info.get("error_curve")?.as_array()?;
        curve
            .iter()
            .filter_map(|p| Some((p.get(0)?.as_u64()? as usize, p.get(1)?.as_f64()?)))
            .filter(|&(k, e)| k <= self.vademecum.modes() && e.is_finite() && e >= 0.0)
            .max_by_key(|&(k, _)| k)
            .map(|(_, e)| e)
    }

    /// The sliver rule the build chose for a cutting session (`info.cut.sliver`, set by
    /// `build --target-error`: [`CutReport::sliver`](crate::offline::CutReport::sliver)); `None` for a bundle that does not say
    /// (the scene's `fidelity.xfem.sliver` applies). An error for a value no sliver rule has.
    pub fn cut_sliver(&self) -> Result<Option<f64>, InfoError> {
        let Some(v) = self.manifest.info.get("cut").and_then(|c| c.get("sliver")) else {
            return Ok(None);
        };
        match v.as_f64() {
            Some(s) if (0.0..0.5).contains(&s) => Ok(Some(s)),
            _ => Err(InfoError {
                key: "cut sliver rule",
                value: v.to_string(),
                expected: "a fraction in [0, 0.5)",
            }),
        }
    }

    /// The bare enrichment's calibrated force error (`info.cut.bare_force_error`: the relative
    /// error estimate of a bare-enrichment session's forces on the cut organ,
    /// [`CutReport::bare_force_error`](crate::offline::CutReport::bare_force_error)); `None` for a bundle that has none (local fields, or
    /// built before the calibration). An error for a value that is not a finite non-negative
    /// number.
    pub fn cut_bare_force_error(&self) -> Result<Option<f64>, InfoError> {
        let Some(v) = self.manifest.info.get("cut").and_then(|c| c.get("bare_force_error")) else {
            return Ok(None);
        };
        match v.as_f64() {
            Some(e) if e.is_finite() && e >= 0.0 => Ok(Some(e)),
            _ => Err(InfoError {
                key: "cut bare_force_error",
                value: v.to_string(),
                expected: "a finite non-negative number",
            }),
        }
    }

    /// The vademecum's modes at `nodes` in node-major f32 ([`NodeMajorField`]): shared by
    /// every session of the bundle (made by the first that asks), so each session's frames do
    /// not keep a copy of their own (`3·modes·4` bytes per node: megabytes on an organ).
    /// Nodes other than the first caller's get a field of their own.
    pub fn surface_field(&self, nodes: &[usize]) -> Arc<NodeMajorField> {
        let shared = self
            .surface_field
            .get_or_init(|| Arc::new(NodeMajorField::new(&self.vademecum, nodes)));
        if shared.nodes() == nodes {
            shared.clone()
        } else {
            Arc::new(NodeMajorField::new(&self.vademecum, nodes))
        }
    }
}

/// The arrays of a grasp site's tearing stage, after its prefix ([`tear_prefix`]).
pub(crate) const TEAR_ARRAYS: [&str; 16] = [
    "meta",
    "pod_basis",
    "singular_values",
    "lo",
    "hi",
    "spatial",
    "factors",
    "ritz_v",
    "ritz_k",
    "ritz_b",
    "patterns",
    "load_nodes",
    "load",
    "force_error",
    "fallback_modes",
    "fallback_force_error",
];

/// The bundle's names of grasp site `k`'s tearing arrays: `tear_…` for the scene's grasp
/// (as bundles before grasp sites), `tear{k}_…` for the others.
pub(crate) fn tear_prefix(k: usize) -> String {
    if k == 0 { "tear_".into() } else { format!("tear{k}_") }
}

/// Reads one grasp site's tearing arrays (names after `prefix`).
fn read_tear(dir: &Path, manifest: &Manifest, prefix: &str) -> Result<TearArrays, String> {
    let f = |name: &str| bundle::read_f64(dir, manifest, &format!("{prefix}{name}")).map_err(|e| e.to_string());
    let has = |name: &str| manifest.arrays.contains_key(&format!("{prefix}{name}"));
    let (_, meta) = f("meta")?;
    let (ks, ritz_k) = f("ritz_k")?;
    let (fs, factors) = f("factors")?;
    if meta.len() != 2 || ks.len() != 3 || fs.len() != 3 || !(meta[1] >= 2.0 && meta[1] <= 1e6) {
        return Err(format!(
            "tearing arrays {prefix}* have the wrong shapes: meta {}, ritz_k {ks:?}, factors {fs:?}",
            meta.len()
        ));
    }
    let n_modes = fs[0] as usize;
    // mode counts per pull pattern (empty when the bundle has no such array)
    let counts = |name: &str| -> Result<Vec<usize>, String> {
        if !has(name) {
            return Ok(Vec::new());
        }
        let p = f(name)?.1;
        if !p.iter().all(|&n| n >= 0.0 && n.fract() == 0.0 && n <= 1e6) {
            return Err(format!("{prefix}{name} holds {p:?}: mode counts expected"));
        }
        Ok(p.iter().map(|&n| n as usize).collect())
    };
    let patterns = if has("patterns") { counts("patterns")? } else { vec![n_modes] };
    let (load_nodes, load_forces) = if has("load_nodes") {
        let (_, nodes) = bundle::read_i64(dir, manifest, &format!("{prefix}load_nodes")).map_err(|e| e.to_string())?;
        if nodes.iter().any(|&n| n < 0) {
            return Err(format!("{prefix}load_nodes holds a negative node index"));
        }
        (nodes.iter().map(|&n| n as usize).collect(), f("load")?.1)
    } else {
        (Vec::new(), Vec::new())
    };
    let table = |name: &str| if has(name) { f(name).map(|t| t.1) } else { Ok(Vec::new()) };
    Ok(TearArrays {
        force_error: table("force_error")?,
        fallback_modes: counts("fallback_modes")?,
        fallback_force_error: table("fallback_force_error")?,
        patterns,
        pod_basis: f("pod_basis")?.1,
        singular_values: f("singular_values")?.1,
        captured: meta[0],
        lo: f("lo")?.1,
        hi: f("hi")?.1,
        grid: meta[1] as usize,
        spatial: f("spatial")?.1,
        factors,
        ritz_v: f("ritz_v")?.1,
        ritz_k,
        ritz_b: f("ritz_b")?.1,
        n_modes,
        m: ks[1] as usize,
        load_nodes,
        load_forces,
    })
}

/// Loads and verifies a bundle (format, version, kind, checksums, shapes, consistency).
pub fn load_bundle(dir: &Path) -> Result<LoadedBundle, BundleError> {
    let manifest = bundle::read_manifest(dir)?;
    let bad = |message: String| BundleError::Malformed {
        path: dir.to_path_buf(),
        message,
    };
    if manifest.kind != KIND {
        return Err(bad(format!("bundle kind '{}' is not '{KIND}'", manifest.kind)));
    }
    let (fs, f) = bundle::read_f64(dir, &manifest, "F")?;
    let (gs, g) = bundle::read_f64(dir, &manifest, "G")?;
    let (_, loads) = bundle::read_i64(dir, &manifest, "load_nodes")?;
    let (ns, nodes) = bundle::read_f64(dir, &manifest, "nodes")?;
    let (_, surface) = bundle::read_i64(dir, &manifest, "surface")?;
    let (_, patch_ptr) = bundle::read_i64(dir, &manifest, "patch_ptr")?;
    let (_, patch_nodes) = bundle::read_i64(dir, &manifest, "patch_nodes")?;
    let (_, patch_weights) = bundle::read_f64(dir, &manifest, "patch_weights")?;
    if fs.len() != 2 || gs.len() != 2 || ns.len() != 2 || ns[1] != 3 || fs[0] != gs[0] || fs[1] != 3 * ns[0] {
        return Err(bad(format!("inconsistent array shapes: F {fs:?}, G {gs:?}, nodes {ns:?}")));
    }
    let n_nodes = ns[0] as usize;
    let to_index = |v: &i64| -> Result<usize, BundleError> {
        if *v < 0 || *v as usize >= n_nodes {
            Err(bad(format!("node index {v} out of range (0..{n_nodes})")))
        } else {
            Ok(*v as usize)
        }
    };
    let load_nodes = loads.iter().map(to_index).collect::<Result<Vec<_>, _>>()?;
    let surface_idx = surface.iter().map(to_index).collect::<Result<Vec<_>, _>>()?;
    if patch_ptr.len() != load_nodes.len() + 1 || patch_nodes.len() != patch_weights.len() {
        return Err(bad("load patch arrays do not match the load nodes".into()));
    }
    let mut patches = Vec::with_capacity(load_nodes.len());
    for w in patch_ptr.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a < 0 || b < a || b as usize > patch_nodes.len() {
            return Err(bad("load patch offsets are not increasing".into()));
        }
        let nodes = patch_nodes[a as usize..b as usize]
            .iter()
            .map(to_index)
            .collect::<Result<Vec<_>, _>>()?;
        patches.push((nodes, patch_weights[a as usize..b as usize].to_vec()));
    }
    let mut vademecum = Vademecum::from_parts(n_nodes, fs[0] as usize, load_nodes, patches, f, g).map_err(|e| bad(e.to_string()))?;
    let (_, local_ptr) = bundle::read_i64(dir, &manifest, "local_ptr")?;
    let (_, local_nbr) = bundle::read_i64(dir, &manifest, "local_nbr")?;
    let (_, local_c) = bundle::read_f64(dir, &manifest, "local_c")?;
    if !local_nbr.is_empty() {
        let nonneg = |v: &[i64]| v.iter().all(|&x| x >= 0);
        if !nonneg(&local_ptr) || !nonneg(&local_nbr) || local_c.len() != 9 * local_nbr.len() {
            return Err(bad("local compliance arrays are inconsistent".into()));
        }
        let local = LocalCompliance {
            ptr: local_ptr.iter().map(|&x| x as usize).collect(),
            nbr: local_nbr.iter().map(|&x| x as usize).collect(),
            c: local_c
                .chunks_exact(9)
                .map(|c| [[c[0], c[1], c[2]], [c[3], c[4], c[5]], [c[6], c[7], c[8]]])
                .collect(),
        };
        vademecum = vademecum.with_local(local).map_err(|e| bad(e.to_string()))?;
    }
    let anm = if manifest.arrays.contains_key("anm_nodes") {
        let f = |name: &str| bundle::read_f64(dir, &manifest, name).map(|(_, v)| v);
        let i = |name: &str| bundle::read_i64(dir, &manifest, name).map(|(_, v)| v);
        let arrays = LatticeArrays {
            max_force: f("anm_max_force")?,
            nodes: i("anm_nodes")?,
            points: f("anm_points")?,
            normals: f("anm_normals")?,
            d_linear: f("anm_d_linear")?,
            modes: i("anm_modes")?,
            probe: f("anm_probe")?,
            step_ptr: i("anm_step_ptr")?,
            step_meta: f("anm_step_meta")?,
            step_data: f("anm_step_data")?,
        };
        Some(AnmLattice::from_arrays(&arrays, n_nodes).map_err(bad)?)
    } else {
        None
    };
    let cut_basis = if manifest.arrays.contains_key("cut_basis") {
        let (shape, x) = bundle::read_f64(dir, &manifest, "cut_basis")?;
        let basis = manifest
            .info
            .get("cut")
            .and_then(|c| c.get("basis"))
            .and_then(|b| serde_json::from_value::<RitzBasis>(b.clone()).ok())
            .ok_or_else(|| bad("cut_basis without its basis kind in info.cut.basis".into()))?;
        if shape.len() != 2 || shape[1] == 0 {
            return Err(bad(format!("cut_basis has shape {shape:?}, not [free dofs, directions]")));
        }
        Some(CutBasis {
            basis,
            x: x.into(),
            size: shape[1] as usize,
        })
    } else {
        None
    };
    let mut tear = Vec::new();
    while manifest.arrays.contains_key(&format!("{}meta", tear_prefix(tear.len()))) {
        tear.push(Arc::new(read_tear(dir, &manifest, &tear_prefix(tear.len())).map_err(bad)?));
    }
    // the build's report says how many grasp sites it made: the scene's, and one per entry of
    // `tear_sites`; a bundle missing a site's arrays would load fewer without a word
    if manifest.info.get("tear").is_some_and(|t| !t.is_null()) {
        let built = 1 + manifest.info.get("tear_sites").and_then(|s| s.as_array()).map_or(0, Vec::len);
        if tear.len() != built {
            return Err(bad(format!(
                "its build made {built} grasp site(s) but it holds the tearing arrays of {} (a `tear{{k}}_meta` entry is missing): rebuild it with `vademecum build`",
                tear.len()
            )));
        }
    }
    Ok(LoadedBundle {
        anm,
        cut_basis,
        tear,
        manifest,
        vademecum,
        nodes: nodes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        surface: surface_idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        surface_field: std::sync::OnceLock::new(),
    })
}

/// Checks that a bundle was built from this scene and this mesh: the same scene text, or a
/// text that builds the same ([`Scene::builds_like`]: it differs in runtime settings,
/// comments or layout only).
pub fn check_matches(dir: &Path, manifest: &Manifest, scene: &Scene, mesh: &Mesh) -> Result<(), BundleError> {
    let scene_hash = bundle::sha256_hex(scene.source.as_bytes());
    let builds_like = || {
        bundle::read_scene(dir, manifest)
            .ok()
            .and_then(|text| toml::from_str::<crate::scene::schema::SceneFile>(&text).ok())
            .is_some_and(|built| scene.builds_like(&built))
    };
    if manifest.scene_sha256 != scene_hash && !builds_like() {
        return Err(BundleError::Mismatch {
            path: dir.to_path_buf(),
            what: "scene",
            expected: manifest.scene_sha256.chars().take(12).collect(),
            found: scene_hash[..12].to_string(),
        });
    }
    let mesh_hash = bundle::mesh_hash(mesh);
    if manifest.mesh_sha256 != mesh_hash {
        return Err(BundleError::Mismatch {
            path: dir.to_path_buf(),
            what: "mesh",
            expected: manifest.mesh_sha256.chars().take(12).collect(),
            found: mesh_hash[..12].to_string(),
        });
    }
    Ok(())
}
