//! Reading the files a user names (meshes, scenes, visual surfaces): only regular files, and
//! never more than a stated bound. A FIFO would block the reader for ever, a device such as
//! `/dev/zero` would feed it without end, and a symbolic link may lead to either: each is
//! refused before it is opened, with what it is.

use std::io::{self, Read};
use std::path::Path;

/// Most bytes of a mesh file (a Gmsh or VTK file of the largest mesh a scene may hold is far
/// smaller: 20 million cells of the largest built-in, in ASCII, is about 1.5 GB).
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// Most bytes of a scene file (a scene is a page of TOML).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

/// Most bytes of a visual surface (OBJ): a million-vertex surface is about 60 MB.
pub const MAX_VISUAL_BYTES: u64 = 512 << 20;

/// Checks that `path` (followed through links) is a regular file of at most `max` bytes.
pub fn check_regular(path: &Path, max: u64) -> io::Result<()> {
    let meta = std::fs::metadata(path)?;
    let t = meta.file_type();
    if !t.is_file() {
        use std::os::unix::fs::FileTypeExt;
        let what = if t.is_dir() {
            "a folder"
        } else if t.is_fifo() {
            "a FIFO (named pipe)"
        } else if t.is_char_device() || t.is_block_device() {
            "a device"
        } else if t.is_socket() {
            "a socket"
        } else {
            "not a regular file"
        };
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("it is {what}, not a regular file"),
        ));
    }
    if meta.len() > max {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} bytes, more than the {max} such a file may have", meta.len()),
        ));
    }
    Ok(())
}

/// Reads `path` whole after [`check_regular`], reading at most `max` bytes (a file that grows
/// past it meanwhile is refused).
pub fn read_regular(path: &Path, max: u64) -> io::Result<Vec<u8>> {
    check_regular(path, max)?;
    let mut bytes = Vec::new();
    std::fs::File::open(path)?.take(max + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("it grew past {max} bytes while being read"),
        ));
    }
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text.
pub fn read_regular_text(path: &Path, max: u64) -> io::Result<String> {
    String::from_utf8(read_regular(path, max)?).map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "it is not UTF-8 text"))
}
