//! Global assembly of the stiffness, the mass and the internal forces over the cells (the
//! numbering and the matrix they fill: [`super::system`]).
//!
//! Dirichlet conditions are applied by elimination: constrained degrees of freedom get no
//! equation, and their prescribed values move to the right-hand side,
//! `K_ff u_f = f_f − K_fc ū_c`. The stored matrix is the lower triangle of `K_ff` in
//! compressed-column form (what faer's sparse Cholesky reads with `Side::Lower`).

use std::sync::Arc;

use super::element::{self, ElementError, ElementScratch, Locking};
use super::nodal::{self, NodalPatches, PatchError};
pub use super::system::{DofMap, SymmetricMatrix, SymmetricPattern, scatter_cell};
use crate::material::LinearElastic;
use crate::mesh::Mesh;

/// The material of each cell, as an index into a table.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialMap {
    /// Distinct materials.
    pub table: Vec<LinearElastic>,
    /// Index into `table` for every cell.
    pub of_cell: Vec<u16>,
    /// Density of every material (kg/m³), same order as `table`.
    pub density: Vec<f64>,
}

impl MaterialMap {
    /// One material and density for every cell.
    pub fn uniform(mat: LinearElastic, density: f64, n_cells: usize) -> Self {
        Self {
            table: vec![mat],
            of_cell: vec![0; n_cells],
            density: vec![density],
        }
    }

    /// The material of cell `c`.
    #[inline]
    pub fn of(&self, c: usize) -> &LinearElastic {
        &self.table[self.of_cell[c] as usize]
    }

    /// The density of cell `c` (kg/m³).
    #[inline]
    pub fn density_of(&self, c: usize) -> f64 {
        self.density[self.of_cell[c] as usize]
    }
}

/// The patterns of the locking options (here, beside the nodal patches they need: the
/// pattern itself is [`super::system`]'s).
impl SymmetricPattern {
    /// The pattern of a stiffness assembled with `locking`: [`build`](Self::build), widened
    /// to a node's neighbours' neighbours for the averaged nodal pressure of tetrahedra
    /// ([`NodalPatches::couplings`]). Degenerate cells fall back to the narrow pattern (the
    /// assembly then reports them).
    pub fn for_locking(mesh: &Mesh, dofs: &DofMap, locking: Locking) -> Self {
        let patches = NodalPatches::when(mesh, locking == Locking::Nodal).ok().flatten();
        Self::with_patches(mesh, dofs, patches.as_ref())
    }

    /// [`build`](Self::build), or with `patches` the pattern the averaged nodal pressure
    /// needs (a node's neighbours' neighbours).
    pub fn with_patches(mesh: &Mesh, dofs: &DofMap, patches: Option<&NodalPatches>) -> Self {
        match patches {
            Some(p) => Self::from_adjacency(&p.couplings(), dofs),
            None => Self::build(mesh, dofs),
        }
    }
}

/// An assembly failed on one cell.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("cell {cell}: {source}")]
pub struct AssemblyError {
    /// The cell.
    pub cell: usize,
    /// What went wrong.
    pub source: ElementError,
}

/// Assembles `K_ff` and adds `−K_fc ū_c` to `rhs` (length `n_free`), where `prescribed` holds
/// `ū` for every degree of freedom (only constrained entries are read).
pub fn assemble_stiffness(
    mesh: &Mesh,
    materials: &MaterialMap,
    locking: Locking,
    dofs: &DofMap,
    pattern: Arc<SymmetricPattern>,
    prescribed: &[f64],
    rhs: &mut [f64],
) -> Result<SymmetricMatrix, AssemblyError> {
    let mut k = SymmetricMatrix::zeros(pattern);
    let n = mesh.kind.nodes_per_cell();
    let nd = 3 * n;
    let mut ke = vec![0.0; nd * nd];
    let mut x = vec![[0.0; 3]; n];
    let mut eqs = vec![None; nd];
    let mut s = ElementScratch::default();
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        element::stiffness(mesh.kind, &x, materials.of(c), locking, &mut s, &mut ke).map_err(|source| AssemblyError { cell: c, source })?;
        let cell = mesh.cell(c);
        for a in 0..n {
            for i in 0..3 {
                eqs[3 * a + i] = dofs.eq(3 * cell[a] + i);
            }
        }
        scatter_cell(&mut k, &ke, cell, &eqs, Some(prescribed), rhs);
    }
    if let Some(patches) = nodal_patches(mesh, locking)? {
        // K_vol = Σ_a (κ_a / V_a) G_a G_aᵀ (module docs of `nodal`)
        let grads = nodal::reference_volume_gradients(mesh, &patches);
        let kappa = nodal::nodal_average(&patches, |c| materials.of(c).bulk());
        let (mut g, mut dense, mut eqs) = (Vec::new(), Vec::new(), Vec::new());
        for a in 0..mesh.n_nodes() {
            patches.gather(mesh, a, &grads, &mut g);
            let w = kappa[a] / patches.volume(a);
            patches.scatter_rank_one(a, w, &g, dofs, &mut k, Some(prescribed), rhs, &mut dense, &mut eqs);
        }
    }
    Ok(k)
}

/// Adds the nodal springs `springs` (N/m per degree of freedom, full length: an elastic
/// foundation) to the diagonal of `K_ff`.
pub fn add_springs(k: &mut SymmetricMatrix, dofs: &DofMap, springs: &[f64]) {
    for (d, &s) in springs.iter().enumerate() {
        if let (true, Some(e)) = (s != 0.0, dofs.eq(d)) {
            let pos = k.pattern.position(e, e).expect("pattern has the diagonal");
            k.values[pos] += s;
        }
    }
}

/// The nodal patches when `locking` averages the pressure over nodes of a tetrahedral mesh.
fn nodal_patches(mesh: &Mesh, locking: Locking) -> Result<Option<NodalPatches>, AssemblyError> {
    NodalPatches::when(mesh, locking == Locking::Nodal).map_err(|e| match e {
        PatchError::Degenerate { cell, volume } => AssemblyError {
            cell,
            source: ElementError::NonPositiveJacobian { det: 6.0 * volume },
        },
        PatchError::NotTetrahedra => unreachable!("`when` builds patches of tetrahedra only"),
    })
}

/// The averaged nodal pressures `p_a = κ_a (θ_a − 1)` and every cell's mean of its nodes'
/// ones, `p̄_e` (small strains; [`nodal`]).
struct NodalPressure {
    grads: Vec<[[f64; 3]; 4]>,
    cell: Vec<f64>,
}

impl NodalPressure {
    fn new(mesh: &Mesh, materials: &MaterialMap, patches: &NodalPatches, u: &[f64]) -> Self {
        let grads = nodal::reference_volume_gradients(mesh, patches);
        let kappa = nodal::nodal_average(patches, |c| materials.of(c).bulk());
        let p: Vec<f64> = nodal::nodal_dilatations(mesh, patches, &grads, u)
            .iter()
            .zip(&kappa)
            .map(|(d, k)| k * d)
            .collect();
        let cell = mesh.cells_iter().map(|c| 0.25 * c.iter().map(|&a| p[a]).sum::<f64>()).collect();
        Self { grads, cell }
    }
}

/// Internal forces `f_int = Σ_e K^e u_e` on every degree of freedom (full length), from the
/// full displacement vector. On constrained dofs, `f_int − f_ext` is the reaction.
pub fn internal_forces(mesh: &Mesh, materials: &MaterialMap, locking: Locking, u: &[f64]) -> Result<Vec<f64>, AssemblyError> {
    let n = mesh.kind.nodes_per_cell();
    let nd = 3 * n;
    let mut f = vec![0.0; u.len()];
    let mut ke = vec![0.0; nd * nd];
    let mut x = vec![[0.0; 3]; n];
    let mut ue = vec![0.0; nd];
    let mut s = ElementScratch::default();
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        element::stiffness(mesh.kind, &x, materials.of(c), locking, &mut s, &mut ke).map_err(|source| AssemblyError { cell: c, source })?;
        let cell = mesh.cell(c);
        for p in 0..nd {
            ue[p] = u[3 * cell[p / 3] + p % 3];
        }
        for p in 0..nd {
            let fp: f64 = (0..nd).map(|q| ke[p * nd + q] * ue[q]).sum();
            f[3 * cell[p / 3] + p % 3] += fp;
        }
    }
    if let Some(patches) = nodal_patches(mesh, locking)? {
        // f_vol = Σ_e p̄_e g_e
        let np = NodalPressure::new(mesh, materials, &patches, u);
        for (c, cell) in mesh.cells_iter().enumerate() {
            for (k, &b) in cell.iter().enumerate() {
                for i in 0..3 {
                    f[3 * b + i] += np.cell[c] * np.grads[c][k][i];
                }
            }
        }
    }
    Ok(f)
}

/// Centre stress of every cell (Voigt, Pa) from the full displacement vector.
pub fn cell_stresses(mesh: &Mesh, materials: &MaterialMap, locking: Locking, u: &[f64]) -> Result<Vec<[f64; 6]>, AssemblyError> {
    let n = mesh.kind.nodes_per_cell();
    let mut x = vec![[0.0; 3]; n];
    let mut ue = vec![0.0; 3 * n];
    let mut s = ElementScratch::default();
    let pressure = nodal_patches(mesh, locking)?.map(|p| NodalPressure::new(mesh, materials, &p, u).cell);
    (0..mesh.n_cells())
        .map(|c| {
            mesh.cell_coords(c, &mut x);
            for (a, &node) in mesh.cell(c).iter().enumerate() {
                ue[3 * a..3 * a + 3].copy_from_slice(&u[3 * node..3 * node + 3]);
            }
            let p = pressure.as_ref().map(|p| p[c]);
            element::stress(mesh.kind, &x, &ue, materials.of(c), locking, p, &mut s).map_err(|source| AssemblyError { cell: c, source })
        })
        .collect()
}

/// Assembles the consistent mass `M_ff` (`M_ab = ρ ∫ N_a N_b dV` times the 3×3 identity) on
/// the stiffness pattern, or its row-sum lumped diagonal when `lumped`.
pub fn assemble_mass(
    mesh: &Mesh,
    materials: &MaterialMap,
    dofs: &DofMap,
    pattern: Arc<SymmetricPattern>,
    lumped: bool,
) -> Result<SymmetricMatrix, AssemblyError> {
    let mut m = SymmetricMatrix::zeros(pattern);
    let n = mesh.kind.nodes_per_cell();
    let mut x = vec![[0.0; 3]; n];
    let mut me = vec![0.0; n * n];
    let mut ml = vec![0.0; n];
    let s = ElementScratch::default();
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        let cell = mesh.cell(c);
        let rho = materials.density_of(c);
        if lumped {
            element::lumped_mass(mesh.kind, &x, rho, &s, &mut ml).map_err(|source| AssemblyError { cell: c, source })?;
            for a in 0..n {
                for i in 0..3 {
                    if let Some(e) = dofs.eq(3 * cell[a] + i) {
                        let pos = m.pattern.position(e, e).expect("pattern has the diagonal");
                        m.values[pos] += ml[a];
                    }
                }
            }
        } else {
            element::consistent_mass(mesh.kind, &x, rho, &s, &mut me).map_err(|source| AssemblyError { cell: c, source })?;
            for a in 0..n {
                for b in 0..n {
                    for i in 0..3 {
                        if let (Some(r), Some(col)) = (dofs.eq(3 * cell[a] + i), dofs.eq(3 * cell[b] + i))
                            && r >= col
                        {
                            let pos = m.pattern.position(r, col).expect("pattern covers every cell coupling");
                            m.values[pos] += me[a * n + b];
                        }
                    }
                }
            }
        }
    }
    Ok(m)
}

/// Lumped nodal masses (kg) of every node.
pub fn lumped_masses(mesh: &Mesh, materials: &MaterialMap) -> Result<Vec<f64>, AssemblyError> {
    let n = mesh.kind.nodes_per_cell();
    let mut x = vec![[0.0; 3]; n];
    let mut me = vec![0.0; n];
    let s = ElementScratch::default();
    let mut m = vec![0.0; mesh.n_nodes()];
    for c in 0..mesh.n_cells() {
        mesh.cell_coords(c, &mut x);
        element::lumped_mass(mesh.kind, &x, materials.density_of(c), &s, &mut me).map_err(|source| AssemblyError { cell: c, source })?;
        for (a, &node) in mesh.cell(c).iter().enumerate() {
            m[node] += me[a];
        }
    }
    Ok(m)
}
