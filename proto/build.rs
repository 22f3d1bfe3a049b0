//! Compiles the `.proto` contracts with a vendored `protoc`, so a fresh machine
//! needs no system protobuf install.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protoc = protoc_bin_vendored::protoc_bin_path()?;
    // SAFETY: build scripts are single-threaded; nothing else reads the environment here.
    unsafe { std::env::set_var("PROTOC", protoc) };
    let protos = [
        "vademecum/v1/info.proto",
        "vademecum/v1/session.proto",
        "vademecum/v1/interaction.proto",
        "vademecum/v1/viewing.proto",
        "vademecum/v1/fleet.proto",
    ];
    for p in protos {
        println!("cargo:rerun-if-changed={p}");
    }
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    tonic_prost_build::configure()
        .file_descriptor_set_path(out.join("vademecum_descriptor.bin"))
        .compile_protos(&protos, &["."])?;
    Ok(())
}
