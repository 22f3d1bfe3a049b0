//! Seed 004 Table 5.2: a 0.1 m cube of Abaqus neo-Hookean material (E = 3000 Pa, ν = 0.49),
//! face y = 0 clamped, face y = 0.1 m pulled 0.02 m in y with its x and z motion fixed:
//! strain energy 0.0648 J and reaction 6.11 N. Total Lagrangian hexahedra, Newton–Raphson.

use vademecum_engine::fem::hyperelastic::Volumetric;
use vademecum_engine::fem::linear_static::StaticProblem;
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams, NonlinearSolution};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::mesh::procedural::block_hex;

fn cube(n: usize, volumetric: Volumetric, stretch: f64) -> (NonlinearSolution, Vec<usize>) {
    let mesh = block_hex([0.0; 3], [0.1; 3], [n, n, n]);
    let bottom: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes[i][1].abs() < 1e-9).collect();
    let top: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| (mesh.nodes[i][1] - 0.1).abs() < 1e-9).collect();
    let mut p = StaticProblem::new(mesh.n_nodes());
    p.clamp(&bottom);
    p.prescribe(&top, 0, 0.0);
    p.prescribe(&top, 2, 0.0);
    p.prescribe(&top, 1, 0.1 * stretch);
    let law = Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, 0.49).unwrap());
    let s = nonlinear_static::solve(&mesh, law, volumetric, &p, &NewtonParams::default(), |_| {}).unwrap();
    (s, top)
}

#[test]
fn the_seed_004_cube_matches_table_5_2_within_one_percent_without_locking() {
    let (s, top) = cube(12, Volumetric::MeanDilatation, 0.2);
    let force = s.reaction_sum(&top)[1];
    eprintln!("12³ mean dilatation: W = {:.5} J, F = {:.4} N, {:?}", s.energy, force, s.info);
    assert!((s.energy - 0.0648).abs() < 0.01 * 0.0648, "energy {} J", s.energy);
    assert!((force - 6.11).abs() < 0.01 * 6.11, "reaction {force} N");
    // full integration locks: stiffer by percents
    let (l, top) = cube(12, Volumetric::PointWise, 0.2);
    let locked = l.reaction_sum(&top)[1];
    eprintln!("12³ full integration: W = {:.5} J, F = {:.4} N", l.energy, locked);
    assert!(locked > 1.01 * force, "full integration {locked} N against {force} N");
}
