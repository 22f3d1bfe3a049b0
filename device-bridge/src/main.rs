//! `vademecum-bridge`: the 1 kHz haptic loop beside a vademecum server (see
//! `vademecum_bridge::cli`).

fn main() -> std::process::ExitCode {
    vademecum_bridge::cli::main_entry()
}
