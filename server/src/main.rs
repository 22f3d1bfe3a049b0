//! `vademecum`: the command line of the vademecum simulation server (see
//! [`vademecum_server::cli_main`]).

fn main() -> std::process::ExitCode {
    vademecum_server::cli_main::main_entry()
}
