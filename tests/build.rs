//! Compiles the fake Agones SDK server's contract (tests/proto/) for tests/tests/agones.rs, with
//! the vendored protoc the proto crate uses.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protoc = protoc_bin_vendored::protoc_bin_path()?;
    // SAFETY: build scripts are single-threaded; nothing else reads the environment here.
    unsafe { std::env::set_var("PROTOC", protoc) };
    let protos = ["proto/agones_sdk_fake.proto", "proto/agones_beta_fake.proto"];
    for p in protos {
        println!("cargo:rerun-if-changed={p}");
    }
    tonic_prost_build::configure()
        .build_client(false)
        .compile_protos(&protos, &["proto"])?;
    Ok(())
}
