//! With the `oidn` feature, the test and program binaries find Intel Open
//! Image Denoise where OIDN_DIR says it is, without LD_LIBRARY_PATH.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    if std::env::var_os("CARGO_FEATURE_OIDN").is_none() {
        return;
    }
    if let Some(dir) = std::env::var_os("OIDN_DIR") {
        let lib = PathBuf::from(dir).join("lib");
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    }
}
