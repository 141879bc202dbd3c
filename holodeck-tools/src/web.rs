//! The web display's files, embedded in the binary: the page
//! (`web/page/`) and the display compiled to WebAssembly with its
//! wasm-bindgen glue (built by `build.rs`).

use std::sync::Arc;

use holodeck_server::net::WebAsset;

/// The files `serve --web` serves, or why this build has none.
pub fn assets() -> anyhow::Result<Arc<[WebAsset]>> {
    #[cfg(holodeck_web)]
    {
        Ok(Arc::from(vec![
            WebAsset {
                path: "/index.html",
                content_type: "text/html; charset=utf-8",
                bytes: include_bytes!("../../web/page/index.html"),
            },
            WebAsset {
                path: "/app.js",
                content_type: "text/javascript; charset=utf-8",
                bytes: include_bytes!("../../web/page/app.js"),
            },
            WebAsset {
                path: "/holodeck_web.js",
                content_type: "text/javascript; charset=utf-8",
                bytes: include_bytes!(concat!(env!("OUT_DIR"), "/web/holodeck_web.js")),
            },
            WebAsset {
                path: "/holodeck_web_bg.wasm",
                content_type: "application/wasm",
                bytes: include_bytes!(concat!(env!("OUT_DIR"), "/web/holodeck_web_bg.wasm")),
            },
        ]))
    }
    #[cfg(not(holodeck_web))]
    {
        anyhow::bail!(
            "this holodeck was built without the web display: its build could not compile the page's \
             WebAssembly (run `rustup target add wasm32-unknown-unknown`, then build again)"
        )
    }
}
