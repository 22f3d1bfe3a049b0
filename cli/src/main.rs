//! `vademecum`: the command line of the vademecum simulation server (see [`vademecum_cli`]).

fn main() -> std::process::ExitCode {
    vademecum_cli::main_entry()
}
