//! Compiles relief.v1 with protox (pure Rust), so no system `protoc` is needed.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let proto = "relief/v1/relief.proto";
    println!("cargo:rerun-if-changed={proto}");
    let descriptors = protox::compile([proto], ["."])?;
    let out_dir = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    let descriptor_path = out_dir.join("relief_v1_descriptor.bin");
    std::fs::write(&descriptor_path, prost::Message::encode_to_vec(&descriptors))?;
    // A frame's image is shared by every stream that shows it: Bytes, so
    // each stream's copy is a reference count, not a megabyte.
    tonic_prost_build::configure().bytes(".relief.v1.RenderResponse.image").compile_fds(descriptors)?;
    // serde for every message, in the proto3 JSON mapping (camelCase names,
    // enums by name, 64-bit integers and bytes as strings): the HTTP
    // transport speaks the same messages as gRPC.
    let encoded = std::fs::read(&descriptor_path)?;
    pbjson_build::Builder::new().register_descriptors(&encoded)?.build(&[".relief.v1"])?;
    Ok(())
}
