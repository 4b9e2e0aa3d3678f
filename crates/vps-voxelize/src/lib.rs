//! Voxelization (DESIGN §2). Work in progress: filled by the voxelizer module set.
