//! One module per subcommand: argument definitions and a `run` that calls the libraries.

pub mod admin;
pub mod check;
pub mod compare;
pub mod copy;
pub mod create;
pub mod demo;
pub mod export;
pub mod fill;
pub mod grid;
pub mod import;
pub mod info;
pub mod optimize;
pub mod pict;
pub mod render;
pub mod run;
pub mod sample;
pub mod scene;
pub mod serve;
pub mod view;
