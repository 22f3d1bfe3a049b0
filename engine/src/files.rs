//! The bounds of the files a user names (meshes, scenes, visual surfaces, credentials); they
//! are read through [`vademecum_files`]: only regular files, never more than the bound.

pub use vademecum_files::{check_regular, read_regular, read_regular_text};

/// Most bytes of a mesh file (a Gmsh or VTK file of the largest mesh a scene may hold is far
/// smaller: 20 million cells of the largest built-in, in ASCII, is about 1.5 GB).
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// Most bytes of a scene file (a scene is a page of TOML).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

/// Most bytes of a visual surface (OBJ): a million-vertex surface is about 60 MB.
pub const MAX_VISUAL_BYTES: u64 = 512 << 20;

/// Most bytes of a small credential or configuration file a user names (a token file, a TLS
/// certificate or key, a CA bundle): a page of PEM or a few thousand tokens.
pub const MAX_CREDENTIAL_BYTES: u64 = 1 << 20;
