//! Node and face sets chosen by geometric regions or physical groups.
//!
//! A [`Region`] is what a scene writes for its fixed region, its accessible region and its
//! loads. Geometric tests use a tolerance of `1e-9 ×` the mesh diameter, so a box whose face
//! lies exactly on a layer of nodes selects that layer.

use serde::{Deserialize, Serialize};

use super::Mesh;
use super::boundary::Boundary;

/// A physical group, by name or numeric tag.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum GroupRef {
    /// The numeric physical tag.
    Tag(i64),
    /// The physical name (Gmsh `$PhysicalNames`).
    Name(String),
}

impl std::fmt::Display for GroupRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GroupRef::Tag(t) => write!(f, "{t}"),
            GroupRef::Name(n) => write!(f, "\"{n}\""),
        }
    }
}

/// A region of a mesh. In a scene file it is written as a one-key table, for example
/// `{ box = { min = [0, 0, 0], max = [0.01, 0.1, 0.1] } }`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Region {
    /// Nodes inside an axis-aligned box (m), boundary included.
    Box {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
    /// Nodes on the side of a plane that its normal points to: `(x − point)·normal ≥ 0`.
    HalfSpace {
        /// A point of the plane (m).
        point: [f64; 3],
        /// The normal (need not be unit length).
        normal: [f64; 3],
    },
    /// Nodes within `radius` of `center` (m).
    Sphere {
        /// Centre (m).
        center: [f64; 3],
        /// Radius (m).
        radius: f64,
    },
    /// Nodes of the cells or tagged faces of a physical group.
    Group(GroupRef),
    /// Explicit node indices (0-based).
    Nodes(Vec<usize>),
}

/// Why a region could not be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SelectError {
    /// The mesh has no physical group of that name or tag.
    #[error("the mesh has no physical group {group}{}", known_list(.known))]
    UnknownGroup {
        /// The group asked for.
        group: GroupRef,
        /// Groups the mesh has.
        known: Vec<String>,
    },
    /// A node index is not in the mesh.
    #[error("node {index} does not exist (the mesh has {n_nodes} nodes)")]
    NodeOutOfRange {
        /// The index.
        index: usize,
        /// Number of nodes.
        n_nodes: usize,
    },
    /// A parameter of the region is not usable (NaN, negative radius, zero normal, min > max).
    #[error("{0}")]
    BadParameter(String),
}

fn known_list(k: &[String]) -> String {
    if k.is_empty() {
        " (it has no physical groups)".into()
    } else {
        format!(" (known: {})", k.join(", "))
    }
}

impl Region {
    /// Checks the region's own parameters (finite numbers, positive radius, non-zero normal,
    /// `min ≤ max`).
    pub fn validate(&self) -> Result<(), SelectError> {
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match self {
            Region::Box { min, max } => {
                if !finite(min) || !finite(max) {
                    return Err(SelectError::BadParameter("box corners must be finite numbers".into()));
                }
                if (0..3).any(|k| min[k] > max[k]) {
                    return Err(SelectError::BadParameter(format!(
                        "box min {min:?} exceeds max {max:?} in some axis"
                    )));
                }
            }
            Region::HalfSpace { point, normal } => {
                if !finite(point) || !finite(normal) || normal.iter().all(|x| *x == 0.0) {
                    return Err(SelectError::BadParameter(
                        "half_space needs a finite point and a non-zero normal".into(),
                    ));
                }
            }
            Region::Sphere { center, radius } => {
                if !finite(center) || !radius.is_finite() || *radius <= 0.0 {
                    return Err(SelectError::BadParameter(format!(
                        "sphere needs a finite centre and a positive radius (got {radius})"
                    )));
                }
            }
            Region::Group(_) | Region::Nodes(_) => {}
        }
        Ok(())
    }

    /// The sorted, unique nodes of `mesh` in this region.
    pub fn nodes(&self, mesh: &Mesh) -> Result<Vec<usize>, SelectError> {
        self.validate()?;
        let tol = 1e-9 * mesh.diameter().max(f64::MIN_POSITIVE);
        let pick = |f: &dyn Fn(&[f64; 3]) -> bool| -> Vec<usize> { (0..mesh.n_nodes()).filter(|&i| f(&mesh.nodes[i])).collect() };
        let mut out = match self {
            Region::Box { min, max } => pick(&|p| (0..3).all(|k| p[k] >= min[k] - tol && p[k] <= max[k] + tol)),
            Region::HalfSpace { point, normal } => {
                let len = (normal[0].powi(2) + normal[1].powi(2) + normal[2].powi(2)).sqrt();
                pick(&|p| (0..3).map(|k| (p[k] - point[k]) * normal[k] / len).sum::<f64>() >= -tol)
            }
            Region::Sphere { center, radius } => pick(&|p| (0..3).map(|k| (p[k] - center[k]).powi(2)).sum::<f64>().sqrt() <= radius + tol),
            Region::Group(g) => {
                let tag = self.group_tag(mesh, g)?;
                let mut v = Vec::new();
                for (c, r) in mesh.cell_region.iter().enumerate() {
                    if *r == tag {
                        v.extend_from_slice(mesh.cell(c));
                    }
                }
                if let Some(f) = mesh.tagged_faces.get(&tag) {
                    v.extend(f.triangles.iter().flatten());
                    v.extend(f.quads.iter().flatten());
                }
                v
            }
            Region::Nodes(list) => {
                if let Some(&index) = list.iter().find(|&&i| i >= mesh.n_nodes()) {
                    return Err(SelectError::NodeOutOfRange {
                        index,
                        n_nodes: mesh.n_nodes(),
                    });
                }
                list.clone()
            }
        };
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    /// Nodes of this region that lie on the boundary surface.
    pub fn surface_nodes(&self, mesh: &Mesh, boundary: &Boundary) -> Result<Vec<usize>, SelectError> {
        let inside = self.nodes(mesh)?;
        let on_boundary = boundary.nodes();
        Ok(intersect_sorted(&inside, &on_boundary))
    }

    /// Indices into `boundary.faces` of the faces whose nodes all lie in this region.
    pub fn faces(&self, mesh: &Mesh, boundary: &Boundary) -> Result<Vec<usize>, SelectError> {
        let mut mask = vec![false; mesh.n_nodes()];
        for n in self.nodes(mesh)? {
            mask[n] = true;
        }
        Ok((0..boundary.faces.len())
            .filter(|&f| boundary.faces[f].node_slice().iter().all(|&n| mask[n]))
            .collect())
    }

    fn group_tag(&self, mesh: &Mesh, g: &GroupRef) -> Result<i32, SelectError> {
        let key = match g {
            GroupRef::Tag(t) => t.to_string(),
            GroupRef::Name(n) => n.clone(),
        };
        mesh.group_tag(&key).ok_or_else(|| {
            let mut known: Vec<String> = mesh.group_names.iter().map(|(t, n)| format!("{t} \"{n}\"")).collect();
            let mut tags: Vec<i32> = mesh.cell_region.iter().copied().filter(|t| *t != 0).collect();
            tags.extend(mesh.tagged_faces.keys());
            tags.sort_unstable();
            tags.dedup();
            for t in tags {
                if !mesh.group_names.contains_key(&t) {
                    known.push(t.to_string());
                }
            }
            SelectError::UnknownGroup { group: g.clone(), known }
        })
    }
}

/// Intersection of two sorted, unique index lists.
pub fn intersect_sorted(a: &[usize], b: &[usize]) -> Vec<usize> {
    let (mut i, mut j, mut out) = (0, 0, Vec::new());
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                out.push(a[i]);
                i += 1;
                j += 1;
            }
        }
    }
    out
}

/// The node nearest to `p` (ties: lowest index). `None` for an empty mesh.
pub fn nearest_node(mesh: &Mesh, p: [f64; 3]) -> Option<usize> {
    let d2 = |q: &[f64; 3]| (0..3).map(|k| (q[k] - p[k]).powi(2)).sum::<f64>();
    (0..mesh.n_nodes()).min_by(|&a, &b| d2(&mesh.nodes[a]).total_cmp(&d2(&mesh.nodes[b])))
}
