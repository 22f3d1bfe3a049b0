//! Seed 004 Table 5.2: a 0.1 m cube of Abaqus neo-Hookean material (E = 3000 Pa, ν = 0.49),
//! face y = 0 clamped, face y = 0.1 m pulled 0.02 m in y with its x and z motion fixed:
//! strain energy 0.0648 J and reaction 6.11 N. Total Lagrangian hexahedra, Newton–Raphson.

use vademecum_engine::fem::hyperelastic::{LawMap, Volumetric};
use vademecum_engine::fem::linear_static::StaticProblem;
use vademecum_engine::fem::nonlinear_static::{self, NewtonParams, NonlinearSolution};
use vademecum_engine::material::LinearElastic;
use vademecum_engine::material::hyperelastic::Hyperelastic;
use vademecum_engine::mesh::procedural::block_hex;

fn cube(n: usize, volumetric: Volumetric, stretch: f64) -> (NonlinearSolution, Vec<usize>) {
    let law = Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, 0.49).unwrap());
    let (s, top) = cube_with(n, law, volumetric, stretch);
    (s.unwrap(), top)
}

fn cube_with(
    n: usize,
    law: Hyperelastic,
    volumetric: Volumetric,
    stretch: f64,
) -> (Result<NonlinearSolution, nonlinear_static::NonlinearError>, Vec<usize>) {
    let mesh = block_hex([0.0; 3], [0.1; 3], [n, n, n]);
    let bottom: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes[i][1].abs() < 1e-9).collect();
    let top: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| (mesh.nodes[i][1] - 0.1).abs() < 1e-9).collect();
    let mut p = StaticProblem::new(mesh.n_nodes());
    p.clamp(&bottom);
    p.prescribe(&top, 0, 0.0);
    p.prescribe(&top, 2, 0.0);
    p.prescribe(&top, 1, 0.1 * stretch);
    let s = nonlinear_static::solve(
        &mesh,
        &LawMap::uniform(law, mesh.n_cells()),
        volumetric,
        &p,
        &NewtonParams::default(),
        |_, _| {},
    );
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

#[test]
fn nearly_incompressible_tissue_converges_without_locking() {
    // ν = 0.499: K/μ ≈ 1000
    let law = Hyperelastic::neo_hookean(&LinearElastic::new(3000.0, 0.499).unwrap());
    let (s, top) = cube_with(6, law, Volumetric::MeanDilatation, 0.2);
    let s = s.expect("converges");
    let f = s.reaction_sum(&top)[1];
    assert!(s.energy.is_finite() && f.is_finite());
    // the volume is kept: the reaction is close to the ν = 0.49 value (within 5 %), not
    // locked up by a factor
    let (r49, top49) = cube(6, Volumetric::MeanDilatation, 0.2);
    let f49 = r49.reaction_sum(&top49)[1];
    assert!((f / f49 - 1.0).abs() < 0.05, "ν = 0.499: {f} N, ν = 0.49: {f49} N");
}

#[test]
fn st_venant_kirchhoff_crushed_to_a_fifth_converges_or_stops_with_a_diagnostic_never_nan() {
    // SVK softens under compression (its stress vanishes again at full collapse): crushing
    // the cube to 20 % of its height is beyond its stable range
    let law = Hyperelastic::svk(&LinearElastic::new(3000.0, 0.3).unwrap());
    let (s, _) = cube_with(4, law, Volumetric::PointWise, -0.8);
    eprintln!(
        "SVK crushed to 20 %: {:?}",
        s.as_ref().map(|s| (s.energy, &s.info.cuts)).map_err(|e| e.to_string())
    );
    match s {
        Ok(s) => assert!(s.energy.is_finite() && s.u.iter().all(|v| v.is_finite())),
        Err(e) => {
            let m = e.to_string();
            assert!(m.contains("no equilibrium beyond load factor"), "{m}");
        }
    }
}
