//! Cell volumes and quality measures (what `vademecum mesh info` prints).

use super::{CellKind, Mesh};
use crate::mesh::shape;

/// Signed volume of every cell (m³): `det[x1−x0, x2−x0, x3−x0]/6` for a tetrahedron, the
/// 2×2×2 Gauss sum of `det J` for a hexahedron. Negative means inverted orientation.
pub fn signed_volumes(mesh: &Mesh) -> Vec<f64> {
    let g = shape::hex_gauss_2();
    let hex_dn: Vec<[[f64; 3]; 8]> = g.iter().map(|p| shape::hex_dn(*p)).collect();
    let mut x = vec![[0.0; 3]; mesh.kind.nodes_per_cell()];
    (0..mesh.n_cells())
        .map(|c| {
            mesh.cell_coords(c, &mut x);
            match mesh.kind {
                CellKind::Tet4 => shape::jacobian_det(&x, &shape::TET_DN) / 6.0,
                CellKind::Hex8 => hex_dn.iter().map(|d| shape::jacobian_det(&x, d)).sum(),
            }
        })
        .collect()
}

/// Smallest Jacobian determinant of hexahedron `c` over its eight corners (a twisted cell has
/// a negative one even when its volume is positive). For tetrahedra, `6·volume`.
pub fn min_corner_jacobian(mesh: &Mesh, c: usize) -> f64 {
    let mut x = vec![[0.0; 3]; mesh.kind.nodes_per_cell()];
    mesh.cell_coords(c, &mut x);
    match mesh.kind {
        CellKind::Tet4 => shape::jacobian_det(&x, &shape::TET_DN),
        CellKind::Hex8 => shape::HEX_NODES
            .iter()
            .map(|p| shape::jacobian_det(&x, &shape::hex_dn(*p)))
            .fold(f64::INFINITY, f64::min),
    }
}

const TET_EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
const HEX_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (1, 2),
    (2, 3),
    (3, 0),
    (4, 5),
    (5, 6),
    (6, 7),
    (7, 4),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// The edges of a cell kind, as pairs of local node indices.
pub fn edges(kind: CellKind) -> &'static [(usize, usize)] {
    match kind {
        CellKind::Tet4 => &TET_EDGES,
        CellKind::Hex8 => &HEX_EDGES,
    }
}

/// A summary of a mesh's size and quality.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MeshQuality {
    /// Cell kind.
    pub kind: CellKind,
    /// Number of nodes.
    pub nodes: usize,
    /// Number of nodes referenced by at least one cell.
    pub used_nodes: usize,
    /// Number of cells.
    pub cells: usize,
    /// Bounding box minimum corner.
    pub bbox_min: [f64; 3],
    /// Bounding box maximum corner.
    pub bbox_max: [f64; 3],
    /// Sum of cell volumes.
    pub volume_total: f64,
    /// Smallest signed cell volume.
    pub volume_min: f64,
    /// Largest signed cell volume.
    pub volume_max: f64,
    /// Largest edge-length ratio (longest / shortest edge of a cell).
    pub aspect_max: f64,
    /// Mean edge-length ratio.
    pub aspect_mean: f64,
    /// For tetrahedra, the smallest `q = 6√2·V / l_rms³` (1 for a regular tetrahedron).
    pub tet_quality_min: Option<f64>,
    /// For tetrahedra, the mean of `q`.
    pub tet_quality_mean: Option<f64>,
    /// Cells with negative volume (or a negative corner Jacobian for hexahedra).
    pub inverted: usize,
    /// Cells with zero volume (below 1e-12 of the mean).
    pub degenerate: usize,
    /// Tagged regions and how many cells each holds.
    pub regions: Vec<(i32, usize)>,
}

/// Computes [`MeshQuality`] (does not modify or reject the mesh).
pub fn summarize(mesh: &Mesh) -> MeshQuality {
    let vols = signed_volumes(mesh);
    let n = vols.len().max(1) as f64;
    let mean_abs = vols.iter().map(|v| v.abs()).sum::<f64>() / n;
    let tiny = 1e-12 * mean_abs;
    let mut used = vec![false; mesh.n_nodes()];
    for &i in &mesh.cells {
        used[i] = true;
    }
    let mut x = vec![[0.0; 3]; mesh.kind.nodes_per_cell()];
    let (mut amax, mut asum) = (0.0f64, 0.0);
    let (mut qmin, mut qsum) = (f64::INFINITY, 0.0);
    let mut inverted = 0;
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        let (mut lo, mut hi, mut sq) = (f64::INFINITY, 0.0f64, 0.0);
        for &(a, b) in edges(mesh.kind) {
            let l2: f64 = (0..3).map(|k| (x[a][k] - x[b][k]).powi(2)).sum();
            lo = lo.min(l2.sqrt());
            hi = hi.max(l2.sqrt());
            sq += l2;
        }
        let ratio = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        amax = amax.max(ratio);
        asum += ratio;
        if mesh.kind == CellKind::Tet4 {
            let lrms = (sq / 6.0).sqrt();
            let q = 6.0 * 2f64.sqrt() * vols[c] / lrms.powi(3);
            qmin = qmin.min(q);
            qsum += q;
        }
        let bad = vols[c] < -tiny || (mesh.kind == CellKind::Hex8 && vols[c].abs() > tiny && min_corner_jacobian(mesh, c) <= 0.0);
        if bad {
            inverted += 1;
        }
    }
    let mut regions: std::collections::BTreeMap<i32, usize> = Default::default();
    for r in &mesh.cell_region {
        *regions.entry(*r).or_default() += 1;
    }
    let (bbox_min, bbox_max) = mesh.bounding_box();
    let is_tet = mesh.kind == CellKind::Tet4 && !vols.is_empty();
    MeshQuality {
        kind: mesh.kind,
        nodes: mesh.n_nodes(),
        used_nodes: used.iter().filter(|u| **u).count(),
        cells: mesh.n_cells(),
        bbox_min,
        bbox_max,
        volume_total: vols.iter().sum(),
        volume_min: vols.iter().copied().fold(f64::INFINITY, f64::min),
        volume_max: vols.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        aspect_max: amax,
        aspect_mean: asum / n,
        tet_quality_min: is_tet.then_some(qmin),
        tet_quality_mean: is_tet.then_some(qsum / n),
        inverted,
        degenerate: vols.iter().filter(|v| v.abs() <= tiny).count(),
        regions: regions.into_iter().collect(),
    }
}
