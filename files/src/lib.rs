//! Reading the files a user names (meshes, scenes, visual surfaces, scripts, recordings,
//! token files, certificates): only regular files, and never more than a stated bound. A FIFO
//! would block the reader for ever, a device such as `/dev/zero` would feed it without end,
//! and a symbolic link may lead to either: each is refused before it is opened, with what it
//! is. A leaf crate, so that the engine, the device bridge and the server read alike.

use std::io::{self, Read};
use std::path::Path;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_bound_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f.txt");
        std::fs::write(&file, "hello").unwrap();
        assert_eq!(read_regular_text(&file, 5).unwrap(), "hello");
        let e = read_regular(&file, 4).unwrap_err().to_string();
        assert!(e.contains("more than the 4"), "{e}");
        let e = read_regular(dir.path(), 1 << 20).unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
        let link = dir.path().join("zero");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = read_regular(&link, 1 << 20).unwrap_err().to_string();
        assert!(e.contains("a device"), "{e}");
        let fifo = dir.path().join("pipe");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let e = read_regular(&fifo, 1 << 20).unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
        std::fs::write(&file, [0xff, 0xfe]).unwrap();
        let e = read_regular_text(&file, 5).unwrap_err().to_string();
        assert!(e.contains("UTF-8"), "{e}");
    }
}
