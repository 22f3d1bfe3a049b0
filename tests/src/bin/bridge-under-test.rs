//! The `vademecum-bridge` command line, built as this package's own binary so that the
//! end-to-end tests run it as a separate process (`CARGO_BIN_EXE_bridge-under-test`).

fn main() -> std::process::ExitCode {
    vademecum_bridge::cli::main_entry()
}
