//! Geometry every method shares: `[f64; 3]` vector arithmetic ([`vec3`]) and cuts as level
//! sets with seed 004's visibility criterion ([`cut`]) — the swept blade surface the XFEM, the
//! meshless solver and the scenes all read. Core: it imports nothing above itself.

pub mod cut;
pub mod vec3;
