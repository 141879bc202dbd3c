//! One module per subcommand: argument definitions and a `run` that calls the libraries.

pub mod admin;
pub mod args;
pub mod bench;
pub mod bench_accuracy;
pub mod bench_display;
pub mod bench_network;
pub mod bench_scene_file;
pub mod bench_share;
pub mod bench_tracer;
pub mod check;
pub mod compare;
pub mod create;
pub mod fill;
pub mod grid;
pub mod info;
pub mod optimize;
pub mod pict;
pub mod render;
pub mod run;
pub mod sample;
pub mod scene;
pub mod scene_input;
pub mod serve;
pub mod view;
pub mod window;
