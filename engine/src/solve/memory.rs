//! What a direct solve of a mesh will need in memory, estimated before anything is assembled,
//! so that a mesh too large for the machine is refused with the figure instead of dying in an
//! allocation minutes later.
//!
//! The sparse Cholesky factor dominates: with a fill-reducing ordering its size grows as
//! `n^(4/3)` for `n` unknowns of a 3D mesh. The constant is measured (peak resident memory of
//! `vademecum solve` on structured cubes, 2026-12-02: hex8 20³/30³/40³ cells took 0.29, 1.54 and
//! 4.74 GB, i.e. about 390 bytes × `n^(4/3)`; tetrahedra on the same nodes 0.8 times that; the
//! averaged nodal pressure's wider stencil 2.5 times the plain tetrahedron on the OpenHELP
//! liver). Organ shapes are less compact than cubes and need less: the estimate errs high.

use crate::mesh::{CellKind, Mesh};

/// Bytes per `n^(4/3)` of a hexahedral mesh's solve (measured; module docs).
const BYTES_PER_N43: f64 = 400.0;

/// The estimated peak memory (bytes) of a direct solve on `mesh` with about `3 × nodes`
/// unknowns; `wide` for the averaged nodal pressure's stencil.
pub fn estimate_solve_bytes(mesh: &Mesh, wide: bool) -> u64 {
    let n = 3.0 * mesh.n_nodes() as f64;
    let kind = match (mesh.kind, wide) {
        (CellKind::Hex8, _) => 1.0,
        (CellKind::Tet4, false) => 0.8,
        (CellKind::Tet4, true) => 2.0,
    };
    // plus the mesh and per-cell results (about 1 KB per cell)
    (BYTES_PER_N43 * kind * n.powf(4.0 / 3.0) + 1024.0 * mesh.n_cells() as f64) as u64
}

/// A direct solve the machine cannot hold: its estimate against what is allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "a direct solve of this mesh ({nodes} nodes, {cells} cells) needs about {} of memory, more than the {} allowed; use a coarser mesh (or raise --max-memory if the machine has it)",
    gigabytes(*.need),
    gigabytes(*.limit)
)]
pub struct TooLarge {
    /// The mesh's nodes and cells.
    pub nodes: usize,
    /// Cells.
    pub cells: usize,
    /// The estimate (bytes).
    pub need: u64,
    /// What is allowed (bytes).
    pub limit: u64,
}

/// Refuses a solve whose estimate exceeds `limit` bytes (the memory the system has
/// available, or a user's `--max-memory`), with both figures in the message.
pub fn check(mesh: &Mesh, wide: bool, limit: u64) -> Result<(), TooLarge> {
    let need = estimate_solve_bytes(mesh, wide);
    if need > limit {
        return Err(TooLarge {
            nodes: mesh.n_nodes(),
            cells: mesh.n_cells(),
            need,
            limit,
        });
    }
    Ok(())
}

/// `12.3 GB`.
pub fn gigabytes(bytes: u64) -> String {
    format!("{:.1} GB", bytes as f64 / 1e9)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::procedural::{block_hex, block_tet};

    #[test]
    fn the_estimate_follows_the_measured_cubes_and_refuses_a_huge_one() {
        // measured: 0.29 GB (20³) and 1.54 GB (30³) peak for hex8 cubes; within a factor 1.5
        for (n, gb) in [(20, 0.29), (30, 1.54)] {
            let est = estimate_solve_bytes(&block_hex([0.0; 3], [1.0; 3], [n, n, n]), false) as f64 / 1e9;
            assert!(est > gb / 1.5 && est < gb * 1.5, "{n}³: {est} GB against {gb} GB measured");
        }
        let tets = block_tet([0.0; 3], [1.0; 3], [4, 4, 4]);
        assert!(estimate_solve_bytes(&tets, true) > estimate_solve_bytes(&tets, false));
        let e = check(&block_hex([0.0; 3], [1.0; 3], [40, 40, 40]), false, 1_000_000_000)
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs about") && e.contains("1.0 GB allowed"), "{e}");
    }
}
