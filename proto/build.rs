//! Compiles the `.proto` contracts with a vendored `protoc`, so a fresh machine
//! needs no system protobuf install: ours (`vademecum/v1/`, with a descriptor set for server
//! reflection) and the Agones SDK sidecar's (`agones/`, client and server: the server for the
//! tests' fake sidecar; not in the reflection set, it is not a service this server offers).

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

    let agones = ["agones/sdk.proto", "agones/beta.proto"];
    for p in agones {
        println!("cargo:rerun-if-changed={p}");
    }
    let agones = agones.map(std::path::PathBuf::from);
    let includes = [".".into(), protoc_bin_vendored::include_path()?];
    tonic_prost_build::configure().compile_protos(&agones, &includes)?;
    Ok(())
}
