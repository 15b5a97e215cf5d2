//! Compiles the contract with protox (pure Rust: no protoc on the machines).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let proto = "strider/v1/strider.proto";
    println!("cargo:rerun-if-changed={proto}");
    let fds = protox::compile([proto], ["."])?;
    tonic_prost_build::configure().compile_fds(fds)?;
    Ok(())
}
