//! `include/acdf.h` is what cbindgen generates from `src/lib.rs` with
//! `cbindgen.toml`: a header that differs from the Rust side fails here.
//! `ACDF_BLESS=1 cargo test -p acdf-capi --test header` writes it anew.

#[test]
fn the_header_is_generated_from_the_rust_side() {
    let dir = env!("CARGO_MANIFEST_DIR");
    let config = cbindgen::Config::from_file(format!("{dir}/cbindgen.toml")).unwrap();
    let bindings = cbindgen::Builder::new()
        .with_src(format!("{dir}/src/lib.rs"))
        .with_config(config)
        .generate()
        .expect("cbindgen reads src/lib.rs");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let path = format!("{dir}/include/acdf.h");
    if std::env::var_os("ACDF_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/acdf.h differs from what cbindgen generates from src/lib.rs; \
         regenerate it with ACDF_BLESS=1 cargo test -p acdf-capi --test header"
    );
}
