//! Mesh sources named on the command line: a file path or `builtin:NAME`, loaded by
//! `vps-session` (the same loader scene files use).

pub use vps_session::mesh_source::load;
