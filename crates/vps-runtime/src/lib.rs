//! Real-time runtime. Work in progress.
