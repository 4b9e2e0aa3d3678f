//! Haptic devices. Work in progress.
