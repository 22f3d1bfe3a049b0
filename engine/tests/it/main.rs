//! The engine's integration tests, as modules of one test binary (one link instead of one per
//! file). `no_alloc.rs` stays apart: it installs its own counting global allocator.
//! Run one module with `cargo test -p vademecum-engine --test it damage::`.

mod common;

mod anm_pod;
mod assembly;
mod bad_input;
mod cantilever;
mod composed_session;
mod contact;
mod corotational_session;
mod corotational_xfem;
mod coupled_contact;
mod cut_estimate;
mod cut_target;
mod cutting_session;
mod damage;
mod damage_hard_cases;
mod effect_composition;
mod fuzz;
mod hard_cases;
mod hyperelastic_cube;
mod lame_tet;
mod large_cut;
mod large_palpation;
mod loads_and_boundary;
mod mesh_formats;
mod meshless;
mod patch_tests;
mod pdms_phantom;
mod pgd;
mod progressive_cut;
mod reduced_svk;
mod scenes;
mod shared_meshes;
mod tearing_estimate;
mod tearing_fallback;
mod tearing_pulls;
mod tearing_session;
mod tearing_sites;
mod vademecum;
mod vademecum_accuracy;
mod visual_mapping;
mod visual_split;
mod xfem_cut;
mod xfem_reduced;
