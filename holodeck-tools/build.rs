//! Two things the `holodeck` binary needs from outside Rust's usual build:
//!
//! - With the `oidn` feature, the test and program binaries find Intel Open
//!   Image Denoise where OIDN_DIR says it is, without LD_LIBRARY_PATH.
//! - The web display (`serve --web`): the `holodeck-web` crate is built for
//!   `wasm32-unknown-unknown` by a nested cargo (its own target directory,
//!   `target/web-wasm`), and wasm-bindgen writes its JavaScript glue; both
//!   are embedded in the binary. Where the target is missing (rustup target
//!   add wasm32-unknown-unknown) the binary is built without the web
//!   display, says so here as a warning, and `--web` names what to install.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    println!("cargo::rustc-check-cfg=cfg(holodeck_web)");
    if std::env::var_os("CARGO_FEATURE_OIDN").is_some() {
        if let Some(dir) = std::env::var_os("OIDN_DIR") {
            let lib = PathBuf::from(dir).join("lib");
            println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
        }
    }
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let root = manifest.parent().map(Path::to_path_buf).unwrap_or_default();
    for p in [
        "web/src",
        "web/Cargo.toml",
        "display/src",
        "display/Cargo.toml",
        "protocol/src",
        "protocol/Cargo.toml",
        "Cargo.lock",
    ] {
        println!("cargo:rerun-if-changed={}", root.join(p).display());
    }
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default()).join("web");
    match build_web(&root, &out) {
        Ok(()) => println!("cargo:rustc-cfg=holodeck_web"),
        Err(e) => println!("cargo:warning=the web display is not built into this holodeck: {e}"),
    }
}

/// Builds the web display's WebAssembly and its JavaScript glue into `out`.
fn build_web(root: &Path, out: &Path) -> Result<(), String> {
    let target = "wasm32-unknown-unknown";
    let target_dir = root.join("target").join("web-wasm");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(root)
        .args([
            "build",
            "--release",
            "--locked",
            "-p",
            "holodeck-web",
            "--target",
            target,
        ])
        .arg("--target-dir")
        .arg(&target_dir)
        // A page's code: no debug info, and nothing of the outer build's
        // flags or wrappers (clippy's, say) applies to it.
        .env("CARGO_PROFILE_RELEASE_DEBUG", "0")
        .env("CARGO_PROFILE_RELEASE_PANIC", "abort");
    for var in [
        "RUSTFLAGS",
        "CARGO_ENCODED_RUSTFLAGS",
        "CARGO_BUILD_RUSTFLAGS",
        "RUSTC_WRAPPER",
        "RUSTC_WORKSPACE_WRAPPER",
        "CARGO_TARGET_DIR",
        "CARGO_BUILD_TARGET",
        "CARGO_BUILD_TARGET_DIR",
    ] {
        cmd.env_remove(var);
    }
    let output = cmd.output().map_err(|e| format!("running cargo: {e}"))?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(6).collect();
        let why = tail.into_iter().rev().collect::<Vec<_>>().join(" / ");
        let hint = if stderr.contains("may not be installed") || stderr.contains("target may not be installed") {
            " (rustup target add wasm32-unknown-unknown)"
        } else {
            ""
        };
        return Err(format!("building holodeck-web for {target} failed{hint}: {why}"));
    }
    let wasm = target_dir.join(target).join("release").join("holodeck_web.wasm");
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    wasm_bindgen_cli_support::Bindgen::new()
        .input_path(&wasm)
        .web(true)
        .map_err(|e| format!("wasm-bindgen: {e}"))?
        .typescript(false)
        .debug(false)
        .keep_debug(false)
        .remove_name_section(true)
        .remove_producers_section(true)
        .generate(out)
        .map_err(|e| format!("wasm-bindgen on {}: {e}", wasm.display()))
}
