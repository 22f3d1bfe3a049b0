//! The `vademecum` command line, built as this package's own binary so the end-to-end tests
//! can run it as a separate process (`CARGO_BIN_EXE_vademecum-under-test`) with cargo
//! keeping it up to date — an integration test cannot name another package's binary.

fn main() -> std::process::ExitCode {
    vademecum_cli::main_entry()
}
