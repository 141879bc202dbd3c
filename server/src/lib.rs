//! The holodeck server: the network service (`net`) that samplers, displays
//! and admins connect to, and the scheduler (`schedule`) that decides which
//! beams samplers trace next, over a holodeck file owned by the storage
//! engine of `holodeck_file`.

pub mod net;
pub mod schedule;
