//! Global operators: the assembled mass carries the body's mass for rigid translations, the
//! assembled stiffness is symmetric positive definite once clamped, and the symbolic
//! Cholesky analysis is reused across numeric factorizations of the same pattern.

use std::sync::Arc;

use vademecum_engine::fem::Locking;
use vademecum_engine::fem::assembly::{self, DofMap, MaterialMap, SymmetricPattern};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::mesh::{procedural, quality};
use vademecum_engine::solve::Cholesky;

#[test]
fn mass_matrices_carry_the_body_mass() {
    for mesh in [
        procedural::block_hex([0.0; 3], [0.2, 0.1, 0.1], [4, 2, 2]),
        procedural::lobe(&Default::default()),
    ] {
        let rho = 1060.0;
        let mat = MaterialMap::uniform(LinearElastic::new(1e4, 0.3).unwrap(), rho, mesh.n_cells());
        let dofs = DofMap::new(&vec![false; mesh.n_dofs()]);
        let pattern = Arc::new(SymmetricPattern::build(&mesh, &dofs));
        let mass = rho * quality::signed_volumes(&mesh).iter().sum::<f64>();
        for lumped in [false, true] {
            let m = assembly::assemble_mass(&mesh, &mat, &dofs, pattern.clone(), lumped).unwrap();
            // uᵀ M u for a unit translation along x is the total mass.
            let u: Vec<f64> = (0..mesh.n_dofs()).map(|d| if d % 3 == 0 { 1.0 } else { 0.0 }).collect();
            let mut mu = vec![0.0; u.len()];
            m.mul_vec(&u, &mut mu);
            let got: f64 = u.iter().zip(&mu).map(|(a, b)| a * b).sum();
            assert!((got - mass).abs() < 1e-10 * mass, "lumped={lumped}: {got} vs {mass}");
        }
    }
}

#[test]
fn symbolic_analysis_is_reused_for_a_new_stiffness() {
    let mesh = procedural::block_hex([0.0; 3], [0.3, 0.1, 0.1], [6, 2, 2]);
    let mut constrained = vec![false; mesh.n_dofs()];
    for n in 0..mesh.n_nodes() {
        if mesh.nodes[n][0] == 0.0 {
            constrained[3 * n..3 * n + 3].fill(true);
        }
    }
    let dofs = DofMap::new(&constrained);
    let pattern = Arc::new(SymmetricPattern::build(&mesh, &dofs));
    let prescribed = vec![0.0; mesh.n_dofs()];
    let assemble = |young: f64| {
        let mat = MaterialMap::uniform(LinearElastic::new(young, 0.3).unwrap(), 1.0, mesh.n_cells());
        let mut rhs = vec![0.0; dofs.n_free()];
        assembly::assemble_stiffness(&mesh, &mat, Locking::Bbar, &dofs, pattern.clone(), &prescribed, &mut rhs).unwrap()
    };
    let k1 = assemble(1e4);
    let mut chol = Cholesky::factor(&k1).unwrap();
    let b: Vec<f64> = (0..dofs.n_free()).map(|i| ((i * 37 % 11) as f64 - 5.0) * 1e-2).collect();
    let mut x1 = b.clone();
    chol.solve_in_place(&mut x1);
    // residual of the first solve
    let mut kx = vec![0.0; b.len()];
    k1.mul_vec(&x1, &mut kx);
    let res: f64 = kx.iter().zip(&b).map(|(a, c)| (a - c).powi(2)).sum::<f64>().sqrt();
    assert!(res < 1e-10 * b.iter().map(|v| v * v).sum::<f64>().sqrt());
    // a stiffer material, same pattern: refactor reuses the analysis; x scales by 1/4
    let k4 = assemble(4e4);
    chol.refactor(&k4).unwrap();
    let mut x4 = b.clone();
    chol.solve_in_place(&mut x4);
    for (a, c) in x1.iter().zip(&x4) {
        assert!((a - 4.0 * c).abs() <= 1e-9 * a.abs().max(1e-12), "{a} vs 4×{c}");
    }
}
