//! Finite elements for linear elasticity on tetrahedra and hexahedra.
//!
//! # The method (small strains)
//! Strong form: `−∇·σ(u) = f` in Ω, `u = ū` on Γ_D, `σ·n = t` on Γ_N, with
//! `σ = λ tr(ε) I + 2μ ε`, `ε = ½(∇u + ∇uᵀ)`. Weak form: find u with `u = ū` on Γ_D such that
//! `∫ σ(u):ε(v) = ∫ f·v + ∫_Γ_N t·v` for all v vanishing on Γ_D. With `u = Σ_a N_a u_a`, the
//! cell matrix couples nodes a and b through (index notation, `a_i = ∂N_a/∂x_i`)
//!
//! `K^e_{ai,bj} = ∫_e [ κ a_i b_j + μ (a_j b_i + δ_ij a·b − ⅔ a_i b_j) ] dV`,
//!
//! split into its volumetric part (κ, the bulk modulus) and its deviatoric part (μ). The
//! split is what the locking-free options act on ([`Locking`]).
//!
//! # Layout
//! The shape functions and Jacobians are the mesh's ([`crate::mesh::shape`]).
//! - [`element`]: cell stiffness, mass, stress.
//! - [`assembly`]: degree-of-freedom numbering, sparsity pattern, global assembly.
//! - [`loads`]: nodal forces from point, surface and body loads.
//! - [`nodal`]: the averaged-nodal-pressure tetrahedron (locking-free tet4).
//! - [`linear_static`]: the static solve driver (loads → displacements, reactions, energy).
//! - [`organ`]: [`OrganModel`], the finite-element problem an organ of a scene becomes.

pub mod assembly;
pub mod element;
pub mod hyperelastic;
pub mod linear_static;
pub mod loads;
pub mod nodal;
pub mod nonlinear_static;
pub mod organ;
pub mod system;

pub use element::Locking;
pub use organ::OrganModel;

/// The sum over `nodes` of a field with three components per node (e.g. the reactions on a
/// region, N).
pub fn node_sum(values: &[f64], nodes: &[usize]) -> [f64; 3] {
    let mut s = [0.0; 3];
    for &n in nodes {
        for i in 0..3 {
            s[i] += values[3 * n + i];
        }
    }
    s
}
