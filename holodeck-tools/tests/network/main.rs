//! The networked holodeck with real processes on loopback: servers, sampler
//! workers, displays and admins, each a child process or a raw protocol
//! client. Every wait is for an event the processes report (a log line, a
//! REPORT line, a frame on a socket) under one generous deadline; nothing
//! sleeps to let something happen, and no speed is asserted.

#[path = "../common/mod.rs"]
mod common;

mod admin;
mod browser;
mod displays;
mod faults;
mod harness;
mod lifecycle;
mod proxy;
mod scene_file;
mod scenes;
mod tls;
mod web;
mod window;
