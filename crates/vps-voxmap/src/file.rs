//! Versioned little-endian binary files with a blake3 trailer: `.vmap` (a [`VoxelTree`]) and
//! `.vshell` (a [`PointShell`]).
//!
//! `.vmap` v1: magic `VPSVMAP\0`, u32 version, f64 voxel size (m), 3×f64 origin (m), 3×u32 dims,
//! 3×u8 log2 dims (leaf, lower, upper), then four arenas each as a u64 element count followed by the
//! elements: root slots (u32), upper slots (u32), lower slots (u32), leaf words (u64); then the
//! 32-byte blake3 hash of every byte before it. The hash equals [`VoxelTree::content_hash`].
//! Version 1 holds 2-bit maps (voxel value = [`crate::Voxel`], two bits per voxel in the leaves).
//!
//! `.vmap` v2 (4- and 8-bit maps): v1 with one more header byte after the log2 dims, the bits per
//! voxel (4 or 8); leaves hold that many bits per voxel and tiles a code of that width (the code
//! table is [`crate::VoxelWidth`]'s). 2-bit maps are still written as v1, so their bytes and content
//! hashes are what they were before v2 existed; a v2 header declaring 2 bits is rejected. Reserved
//! codes are rejected on read.
//!
//! `.vmap` v3 (a map with a signed-distance band, [`crate::distance`]): v2's layout with the
//! bits-per-voxel byte (2, 4 or 8) always present, then after the leaf words the band: f64
//! stand-off (m), 3×u32 cube dims, the directory as a u64 count and that many u32 slots, the codes
//! as a u64 count and that many i8. Maps without a band are still written as v1/v2, byte for byte
//! as before; a v1/v2 reader (an older vps) refuses a v3 file by its version.
//!
//! `.vshell` v1: magic `VPSSHEL\0`, u32 version, f64 voxel size (m), u8 method, f64 volume (m³),
//! 3×f64 centre of mass (m), f64 bounding radius (m), u64 point count `n`, `n`×3×f32 points (m),
//! `n`×3×f32 normals, then the blake3 trailer.
//!
//! Readers never trust a length: when the stream's length is known (files), every count is checked
//! against the bytes left before anything is allocated; otherwise arrays grow only as their bytes
//! actually arrive. Either way a corrupt count cannot trigger an allocation larger than the input.
//! Any truncation, flipped byte or trailing data is an error. Writers replace files atomically
//! ([`vps_files::atomic`]): a failed save leaves no truncated file.

use crate::distance;
use crate::shell::ShellMethod;
use crate::tree::{Arenas, TreeConfig, TreeError, VoxelTree};
use crate::{DistanceBand, GridSpec, MassProperties, PointShell, VoxelWidth};
use glam::{DVec3, Vec3};
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use vps_files::atomic::{write_atomically, AtomicStage};

/// Magic bytes opening a `.vmap` file.
pub const VOXMAP_MAGIC: [u8; 8] = *b"VPSVMAP\0";
/// The newest `.vmap` version this build writes (for 4- and 8-bit maps) and reads.
pub const VOXMAP_VERSION: u32 = 2;
/// The `.vmap` version of 2-bit maps (written for them, and read as 2-bit).
pub const VOXMAP_VERSION_2BIT: u32 = 1;
/// The `.vmap` version of maps that carry a signed-distance band (any width).
pub const VOXMAP_VERSION_DISTANCE: u32 = 3;
/// Magic bytes opening a `.vshell` file.
pub const SHELL_MAGIC: [u8; 8] = *b"VPSSHEL\0";
/// The `.vshell` version this build writes and reads.
pub const SHELL_VERSION: u32 = 1;
/// Largest voxel count a `.vmap` header may declare (2^40).
pub const MAX_VOXELS: u64 = 1 << 40;
/// Largest allowed deviation of a shell normal's length from 1.
pub const NORMAL_TOLERANCE: f32 = 1e-3;

/// Elements decoded per read call, bounding the bytes requested ahead of the data.
const CHUNK_BYTES: usize = 64 * 1024;

/// Why a file could not be written or read. Every variant names the field (or path) at fault.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The data ended inside `field`.
    #[error("{field}: file ends early (truncated)")]
    Truncated {
        /// The field being read.
        field: &'static str,
    },
    /// The file holds no bytes at all.
    #[error("the file is empty (0 bytes; expected a header starting with magic {})", expected.escape_ascii())]
    Empty {
        /// The format's magic.
        expected: [u8; 8],
    },
    /// A count declares more data than the rest of the file holds (checked before allocating).
    #[error("{field}: declares {count} elements ({bytes} bytes), but only {remaining} bytes remain in the file")]
    CountExceedsFile {
        /// The array whose count is at fault.
        field: &'static str,
        /// The declared element count.
        count: u64,
        /// The bytes that count needs.
        bytes: u128,
        /// Bytes left in the file after the count.
        remaining: u64,
    },
    /// An I/O error other than end of file.
    #[error("{field}: {source}")]
    Io {
        /// The field being read or written.
        field: &'static str,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// The file does not start with the expected magic bytes.
    #[error("magic: expected {}, found {}", (expected).escape_ascii(), (found).escape_ascii())]
    BadMagic {
        /// The format's magic.
        expected: [u8; 8],
        /// The first 8 bytes read.
        found: [u8; 8],
    },
    /// The version field names a format this build does not read.
    #[error(
        "version: {found} is not supported (the newest version this build reads is {supported})"
    )]
    UnsupportedVersion {
        /// The version in the file.
        found: u32,
        /// The newest version this build reads.
        supported: u32,
    },
    /// A field's value is out of range or inconsistent with the header.
    #[error("{field}: {reason}")]
    InvalidField {
        /// The field (with element index where one applies, e.g. `normals[12]`).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The tree arenas break a tree invariant.
    #[error("tree: {0}")]
    Tree(#[from] TreeError),
    /// The blake3 trailer does not match the content: the file is corrupted.
    #[error("hash: trailer does not match the content (corrupted file)")]
    HashMismatch,
    /// Bytes follow the hash trailer.
    #[error("trailer: unexpected data after the hash")]
    TrailingBytes,
    /// An error while reading or writing the file at `path`.
    #[error("{}: {source}", path.display())]
    AtPath {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: Box<FileError>,
    },
}

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> FileError {
    FileError::InvalidField {
        field: field.into(),
        reason: reason.into(),
    }
}

// ---------------------------------------------------------------------------------------------
// .vmap

/// Writes `tree` as a `.vmap` stream (unbuffered writes go straight to `w`; wrap it in a
/// `BufWriter` for files).
pub fn write_voxmap(tree: &VoxelTree, w: impl Write) -> Result<(), FileError> {
    Encoder::write_hashed(w, |enc| encode_voxmap_body(tree, enc))
}

/// Reads a `.vmap` stream, validating header, arena lengths, tree invariants and the hash. Arrays
/// grow as their bytes arrive; use [`read_voxmap_sized`] when the length is known.
pub fn read_voxmap(r: impl Read) -> Result<VoxelTree, FileError> {
    decode_voxmap(Decoder::new(r, None))
}

/// [`read_voxmap`] of a stream holding exactly `len` bytes: every arena count is checked against
/// the bytes left before its array is allocated, so memory never exceeds the input's size plus the
/// lookup directory (at most [`crate::tree::DIRECTORY_MAX_BYTES`]).
pub fn read_voxmap_sized(r: impl Read, len: u64) -> Result<VoxelTree, FileError> {
    decode_voxmap(Decoder::new(r, Some(len)))
}

fn decode_voxmap(mut dec: Decoder<impl Read>) -> Result<VoxelTree, FileError> {
    dec.magic(VOXMAP_MAGIC)?;
    let version = dec.version_in(VOXMAP_VERSION_2BIT..=VOXMAP_VERSION_DISTANCE)?;
    let spec = read_spec(&mut dec)?;
    let config = TreeConfig {
        log2_dims: [
            dec.u8("log2_dims[0]")?,
            dec.u8("log2_dims[1]")?,
            dec.u8("log2_dims[2]")?,
        ],
    };
    config.validate()?;
    let width = match version {
        VOXMAP_VERSION_2BIT => VoxelWidth::Two,
        _ => match dec.u8("bits per voxel")? {
            2 if version == VOXMAP_VERSION_DISTANCE => VoxelWidth::Two,
            4 => VoxelWidth::Four,
            8 => VoxelWidth::Eight,
            b => {
                return Err(invalid(
                    "bits per voxel",
                    format!("{b} is not 4 or 8 (2-bit maps are version 1)"),
                ))
            }
        },
    };

    let root_cells = spec
        .dims
        .map(|d| (d as u64).div_ceil(config.extent(2) as u64))
        .iter()
        .product::<u64>();
    let root = dec.counted_u32s("root slots", root_cells)?;
    let upper_len = count_children(&root) * slots_per_node(config, 2);
    let upper = dec.counted_u32s("upper slots", upper_len)?;
    let lower_len = count_children(&upper) * slots_per_node(config, 1);
    let lower = dec.counted_u32s("lower slots", lower_len)?;
    let words_per_leaf = ((width.bits() as u64) << (3 * config.log2_dims[0])).div_ceil(64);
    let leaves = dec.counted_u64s("leaf words", count_children(&lower) * words_per_leaf)?;
    let band = if version == VOXMAP_VERSION_DISTANCE {
        Some(decode_band(&mut dec, &spec)?)
    } else {
        None
    };
    dec.finish()?;
    let arenas = Arenas {
        root,
        upper,
        lower,
        leaves,
    };
    let tree = VoxelTree::from_parts(spec, config, width, arenas)?;
    Ok(match band {
        Some(band) => tree.with_distance_band(band),
        None => tree,
    })
}

/// The band section of a v3 `.vmap` (after the leaf words).
fn decode_band<R: Read>(dec: &mut Decoder<R>, spec: &GridSpec) -> Result<DistanceBand, FileError> {
    let standoff = dec.f64("distance standoff")?;
    let found = [
        dec.u32("distance cube dims[0]")?,
        dec.u32("distance cube dims[1]")?,
        dec.u32("distance cube dims[2]")?,
    ];
    let expected = distance::cube_dims(spec);
    if found != expected {
        return Err(invalid(
            "distance cube dims",
            format!("{found:?}, but the grid's dims imply {expected:?}"),
        ));
    }
    let slots = expected.iter().map(|&d| u64::from(d)).product();
    let directory = dec.counted_u32s("distance directory", slots)?;
    let bricks = directory.iter().filter(|&&v| v >= 2).count() as u64;
    let count = dec.expected_count("distance codes", bricks * distance::BRICK_CODES as u64)?;
    let codes = dec.array(count, "distance codes", |b: [u8; 1]| b[0] as i8)?;
    DistanceBand::from_parts(spec, standoff, found, directory, codes)
        .map_err(|e| invalid("distance band", e.to_string()))
}

/// Writes `tree` to `path` (created or truncated); errors name the path.
pub fn save_voxmap(tree: &VoxelTree, path: impl AsRef<Path>) -> Result<(), FileError> {
    save(path.as_ref(), |w| write_voxmap(tree, w))
}

/// Reads the `.vmap` file at `path`; errors name the path.
pub fn load_voxmap(path: impl AsRef<Path>) -> Result<VoxelTree, FileError> {
    load(path.as_ref(), VOXMAP_MAGIC, read_voxmap_sized)
}

// Defined here, next to the encoding it hashes, so the tree module does not import the file module.
impl VoxelTree {
    /// blake3 of the canonical encoding (spec, config, arenas): equal to the `.vmap` file's trailer.
    /// Because the arenas are canonical, equal spec, config and voxel content give equal hashes.
    /// Allocates nothing; time linear in the stored arenas.
    pub fn content_hash(&self) -> [u8; 32] {
        let mut hasher = blake3::Hasher::new();
        // blake3::Hasher's `Write` impl never fails.
        let _ = encode_voxmap_body(self, &mut hasher);
        hasher.finalize().into()
    }
}

fn encode_voxmap_body(tree: &VoxelTree, w: &mut impl Write) -> io::Result<()> {
    w.write_all(&VOXMAP_MAGIC)?;
    let width = tree.width();
    let band = tree.distance_band();
    let version = match (width, band) {
        (_, Some(_)) => VOXMAP_VERSION_DISTANCE,
        (VoxelWidth::Two, None) => VOXMAP_VERSION_2BIT,
        _ => VOXMAP_VERSION,
    };
    w.write_all(&version.to_le_bytes())?;
    let spec = tree.spec();
    w.write_all(&spec.voxel_size.to_le_bytes())?;
    for c in spec.origin.to_array() {
        w.write_all(&c.to_le_bytes())?;
    }
    for d in spec.dims {
        w.write_all(&d.to_le_bytes())?;
    }
    w.write_all(&tree.config().log2_dims)?;
    if version != VOXMAP_VERSION_2BIT {
        w.write_all(&[width.bits() as u8])?;
    }
    let (root, upper, lower, leaves) = tree.arenas();
    for arena in [root, upper, lower] {
        write_array(w, arena, |x| x.to_le_bytes())?;
    }
    write_array(w, leaves, |x| x.to_le_bytes())?;
    if let Some(band) = band {
        w.write_all(&band.standoff_m().to_le_bytes())?;
        for d in band.cube_dims() {
            w.write_all(&d.to_le_bytes())?;
        }
        write_array(w, band.directory(), |x| x.to_le_bytes())?;
        write_array(w, band.codes(), |x| x.to_le_bytes())?;
    }
    Ok(())
}

fn read_spec<R: Read>(dec: &mut Decoder<R>) -> Result<GridSpec, FileError> {
    let voxel_size = dec.f64_positive("voxel_size")?;
    let origin = dec.dvec3_finite("origin", ["origin.x", "origin.y", "origin.z"])?;
    let dims = [
        dec.u32("dims[0]")?,
        dec.u32("dims[1]")?,
        dec.u32("dims[2]")?,
    ];
    for (axis, &d) in dims.iter().enumerate() {
        if d == 0 || d > i32::MAX as u32 {
            return Err(invalid(
                format!("dims[{axis}]"),
                format!("{d} is outside 1..=i32::MAX"),
            ));
        }
    }
    let spec = GridSpec {
        origin,
        voxel_size,
        dims,
    };
    if spec.voxel_count() > MAX_VOXELS {
        return Err(invalid(
            "dims",
            format!(
                "{dims:?} is {} voxels, over the limit of 2^40",
                spec.voxel_count()
            ),
        ));
    }
    let corner = spec.max_corner();
    if !corner.is_finite() {
        return Err(invalid(
            "dims",
            format!("{dims:?} voxels of {voxel_size} m from origin {origin} reach a non-finite corner {corner}"),
        ));
    }
    Ok(spec)
}

fn slots_per_node(config: TreeConfig, level: usize) -> u64 {
    1 << (3 * config.log2_dims[level])
}

/// Slots holding a child (not a tile).
fn count_children(slots: &[u32]) -> u64 {
    slots.iter().filter(|&&s| s >> 31 == 0).count() as u64
}

// ---------------------------------------------------------------------------------------------
// .vshell

/// Writes `shell` as a `.vshell` stream. Errors if `points` and `normals` differ in length.
pub fn write_shell(shell: &PointShell, w: impl Write) -> Result<(), FileError> {
    if shell.points.len() != shell.normals.len() {
        return Err(invalid(
            "normals",
            format!(
                "{} normals for {} points",
                shell.normals.len(),
                shell.points.len()
            ),
        ));
    }
    Encoder::write_hashed(w, |enc| encode_shell_body(shell, enc))
}

/// Reads a `.vshell` stream, validating every field, every point and normal, and the hash. Arrays
/// grow as their bytes arrive; use [`read_shell_sized`] when the length is known.
pub fn read_shell(r: impl Read) -> Result<PointShell, FileError> {
    decode_shell(Decoder::new(r, None))
}

/// [`read_shell`] of a stream holding exactly `len` bytes: the point count is checked against the
/// bytes left before the arrays are allocated.
pub fn read_shell_sized(r: impl Read, len: u64) -> Result<PointShell, FileError> {
    decode_shell(Decoder::new(r, Some(len)))
}

fn decode_shell(mut dec: Decoder<impl Read>) -> Result<PointShell, FileError> {
    dec.magic(SHELL_MAGIC)?;
    dec.version(SHELL_VERSION)?;
    let voxel_size = dec.f64_positive("voxel_size")?;
    let method = match dec.u8("method")? {
        0 => ShellMethod::VoxelCentres,
        1 => ShellMethod::ExactSurface,
        m => return Err(invalid("method", format!("{m} is not 0 or 1"))),
    };
    let volume = dec.f64_non_negative("mass.volume")?;
    let center_of_mass = dec.dvec3_finite(
        "mass.center_of_mass",
        [
            "mass.center_of_mass.x",
            "mass.center_of_mass.y",
            "mass.center_of_mass.z",
        ],
    )?;
    let bounding_radius = dec.f64_non_negative("mass.bounding_radius")?;
    let count = dec.u64("point count")?;
    // Points and normals share the count: both arrays must fit in what is left.
    dec.check_fits("point count", count, 24)?;
    let points = dec.array(count, "points", decode_vec3)?;
    let normals = dec.array(count, "normals", decode_vec3)?;
    dec.finish()?;
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("points[{i}]"), "not finite"));
    }
    // Unit, or exactly zero: a point of a part with no inside (two-sided, no side of its own).
    if let Some(i) = normals.iter().position(|n| {
        !n.is_finite() || (*n != Vec3::ZERO && (n.length() - 1.0).abs() > NORMAL_TOLERANCE)
    }) {
        return Err(invalid(
            format!("normals[{i}]"),
            "not a finite unit vector (nor zero)",
        ));
    }
    Ok(PointShell {
        points,
        normals,
        voxel_size,
        method,
        mass: MassProperties {
            volume,
            center_of_mass,
            bounding_radius,
        },
    })
}

/// Writes `shell` to `path` (created or truncated); errors name the path.
pub fn save_shell(shell: &PointShell, path: impl AsRef<Path>) -> Result<(), FileError> {
    save(path.as_ref(), |w| write_shell(shell, w))
}

/// Reads the `.vshell` file at `path`; errors name the path.
pub fn load_shell(path: impl AsRef<Path>) -> Result<PointShell, FileError> {
    load(path.as_ref(), SHELL_MAGIC, read_shell_sized)
}

fn encode_shell_body(shell: &PointShell, w: &mut impl Write) -> io::Result<()> {
    w.write_all(&SHELL_MAGIC)?;
    w.write_all(&SHELL_VERSION.to_le_bytes())?;
    w.write_all(&shell.voxel_size.to_le_bytes())?;
    w.write_all(&[shell.method as u8])?;
    let m = &shell.mass;
    let scalars = [
        m.volume,
        m.center_of_mass.x,
        m.center_of_mass.y,
        m.center_of_mass.z,
    ];
    for x in scalars.into_iter().chain([m.bounding_radius]) {
        w.write_all(&x.to_le_bytes())?;
    }
    write_array(w, &shell.points, encode_vec3)?;
    // The count is shared with the points; write the normals without a second one.
    write_elements(w, &shell.normals, encode_vec3)
}

fn encode_vec3(v: &Vec3) -> [u8; 12] {
    let mut b = [0u8; 12];
    for (dst, c) in b.chunks_exact_mut(4).zip(v.to_array()) {
        dst.copy_from_slice(&c.to_le_bytes());
    }
    b
}

fn decode_vec3(b: [u8; 12]) -> Vec3 {
    let c = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    Vec3::new(c(0), c(4), c(8))
}

// ---------------------------------------------------------------------------------------------
// Shared plumbing

fn save(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), FileError>,
) -> Result<(), FileError> {
    write_atomically(path, write, |stage, source| FileError::Io {
        field: match stage {
            AtomicStage::Create => "create",
            AtomicStage::Write => "write",
            AtomicStage::Rename => "rename",
        },
        source,
    })
    .map_err(|source| FileError::AtPath {
        path: path.to_path_buf(),
        source: Box::new(source),
    })
}

fn load<T>(
    path: &Path,
    magic: [u8; 8],
    read: impl FnOnce(BufReader<File>, u64) -> Result<T, FileError>,
) -> Result<T, FileError> {
    let at_path = |source| FileError::AtPath {
        path: path.to_path_buf(),
        source: Box::new(source),
    };
    let io = |field, source| at_path(FileError::Io { field, source });
    let (file, len) = vps_files::open_regular(path).map_err(|source| io("open", source))?;
    if len == 0 {
        return Err(at_path(FileError::Empty { expected: magic }));
    }
    read(BufReader::new(file), len).map_err(at_path)
}

/// Writes a u64 element count, then the elements.
fn write_array<T, const N: usize>(
    w: &mut impl Write,
    items: &[T],
    encode: impl Fn(&T) -> [u8; N],
) -> io::Result<()> {
    w.write_all(&(items.len() as u64).to_le_bytes())?;
    write_elements(w, items, encode)
}

/// Writes the elements, batched into `CHUNK_BYTES` buffers.
fn write_elements<T, const N: usize>(
    w: &mut impl Write,
    items: &[T],
    encode: impl Fn(&T) -> [u8; N],
) -> io::Result<()> {
    let mut buf = Vec::with_capacity(CHUNK_BYTES);
    for batch in items.chunks(CHUNK_BYTES / N) {
        buf.clear();
        for item in batch {
            buf.extend_from_slice(&encode(item));
        }
        w.write_all(&buf)?;
    }
    Ok(())
}

/// A writer that hashes everything it passes on, then appends the hash.
struct Encoder<W: Write> {
    inner: W,
    hasher: blake3::Hasher,
}

impl<W: Write> Encoder<W> {
    fn new(inner: W) -> Self {
        Self {
            inner,
            hasher: blake3::Hasher::new(),
        }
    }

    /// Writes what `body` writes to `inner`, then the blake3 of those bytes (the trailer).
    fn write_hashed(
        inner: W,
        body: impl FnOnce(&mut Self) -> io::Result<()>,
    ) -> Result<(), FileError> {
        let mut enc = Self::new(inner);
        body(&mut enc).map_err(|source| FileError::Io {
            field: "write",
            source,
        })?;
        enc.finish()
    }

    fn finish(mut self) -> Result<(), FileError> {
        let hash = self.hasher.finalize();
        self.inner
            .write_all(hash.as_bytes())
            .and_then(|()| self.inner.flush())
            .map_err(|source| FileError::Io {
                field: "hash",
                source,
            })
    }
}

impl<W: Write> Write for Encoder<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// A reader of typed little-endian fields that hashes everything it consumes.
struct Decoder<R: Read> {
    inner: R,
    hasher: blake3::Hasher,
    /// Bytes left in the stream, when its length is known.
    remaining: Option<u64>,
}

impl<R: Read> Decoder<R> {
    fn new(inner: R, len: Option<u64>) -> Self {
        Self {
            inner,
            hasher: blake3::Hasher::new(),
            remaining: len,
        }
    }

    fn fill(&mut self, buf: &mut [u8], field: &'static str) -> Result<(), FileError> {
        read_field(&mut self.inner, buf, field)?;
        self.hasher.update(buf);
        if let Some(left) = &mut self.remaining {
            *left = left.saturating_sub(buf.len() as u64);
        }
        Ok(())
    }

    /// Checks that `count` elements of `bytes_each` fit in the rest of a stream of known length
    /// (the 32-byte hash trailer included), before anything is allocated for them.
    fn check_fits(
        &self,
        field: &'static str,
        count: u64,
        bytes_each: u64,
    ) -> Result<(), FileError> {
        let Some(remaining) = self.remaining else {
            return Ok(());
        };
        let bytes = u128::from(count) * u128::from(bytes_each);
        if bytes + 32 > u128::from(remaining) {
            return Err(FileError::CountExceedsFile {
                field,
                count,
                bytes,
                remaining,
            });
        }
        Ok(())
    }

    fn bytes<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], FileError> {
        let mut b = [0u8; N];
        self.fill(&mut b, field)?;
        Ok(b)
    }

    fn u8(&mut self, field: &'static str) -> Result<u8, FileError> {
        Ok(self.bytes::<1>(field)?[0])
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, FileError> {
        Ok(u32::from_le_bytes(self.bytes(field)?))
    }

    fn u64(&mut self, field: &'static str) -> Result<u64, FileError> {
        Ok(u64::from_le_bytes(self.bytes(field)?))
    }

    fn f64(&mut self, field: &'static str) -> Result<f64, FileError> {
        Ok(f64::from_le_bytes(self.bytes(field)?))
    }

    /// An `f64` that must be finite and > 0 (a voxel size); the error names `field` and the value.
    fn f64_positive(&mut self, field: &'static str) -> Result<f64, FileError> {
        let v = self.f64(field)?;
        if !(v.is_finite() && v > 0.0) {
            return Err(invalid(field, format!("{v} is not finite and > 0")));
        }
        Ok(v)
    }

    /// A vector read from the `f64` fields `parts` (x, y, z) that must be finite; the error names
    /// `field` and the vector.
    fn dvec3_finite(
        &mut self,
        field: &'static str,
        parts: [&'static str; 3],
    ) -> Result<DVec3, FileError> {
        let v = DVec3::new(
            self.f64(parts[0])?,
            self.f64(parts[1])?,
            self.f64(parts[2])?,
        );
        if !v.is_finite() {
            return Err(invalid(field, format!("{v} is not finite")));
        }
        Ok(v)
    }

    /// An `f64` that must be finite and >= 0; the error names `field` and the value.
    fn f64_non_negative(&mut self, field: &'static str) -> Result<f64, FileError> {
        let v = self.f64(field)?;
        if !(v.is_finite() && v >= 0.0) {
            return Err(invalid(field, format!("{v} is not finite and >= 0")));
        }
        Ok(v)
    }

    fn magic(&mut self, expected: [u8; 8]) -> Result<(), FileError> {
        let found = self.bytes::<8>("magic")?;
        if found != expected {
            return Err(FileError::BadMagic { expected, found });
        }
        Ok(())
    }

    /// Reads the version and checks it is in `range`; returns it.
    fn version_in(&mut self, range: std::ops::RangeInclusive<u32>) -> Result<u32, FileError> {
        let found = self.u32("version")?;
        if !range.contains(&found) {
            return Err(FileError::UnsupportedVersion {
                found,
                supported: *range.end(),
            });
        }
        Ok(found)
    }

    fn version(&mut self, supported: u32) -> Result<(), FileError> {
        let found = self.u32("version")?;
        if found != supported {
            return Err(FileError::UnsupportedVersion { found, supported });
        }
        Ok(())
    }

    /// Reads `count` elements of `N` bytes. The Vec grows only as bytes arrive, so a corrupt count
    /// on a short stream fails with `Truncated` after allocating at most the stream's size.
    fn array<T, const N: usize>(
        &mut self,
        count: u64,
        field: &'static str,
        decode: impl Fn([u8; N]) -> T,
    ) -> Result<Vec<T>, FileError> {
        self.check_fits(field, count, N as u64)?;
        let per_chunk = (CHUNK_BYTES / N) as u64;
        let mut out = Vec::with_capacity(count.min(per_chunk) as usize);
        let mut buf = vec![0u8; CHUNK_BYTES];
        let mut left = count;
        while left > 0 {
            let n = left.min(per_chunk) as usize;
            let bytes = &mut buf[..n * N];
            self.fill(bytes, field)?;
            out.extend(bytes.chunks_exact(N).map(|c| {
                let mut a = [0u8; N];
                a.copy_from_slice(c);
                decode(a)
            }));
            left -= n as u64;
        }
        Ok(out)
    }

    /// Reads a u64 count that must equal `expected`, then that many u32s.
    fn counted_u32s(&mut self, field: &'static str, expected: u64) -> Result<Vec<u32>, FileError> {
        let count = self.expected_count(field, expected)?;
        self.array(count, field, u32::from_le_bytes)
    }

    /// Reads a u64 count that must equal `expected`, then that many u64s.
    fn counted_u64s(&mut self, field: &'static str, expected: u64) -> Result<Vec<u64>, FileError> {
        let count = self.expected_count(field, expected)?;
        self.array(count, field, u64::from_le_bytes)
    }

    fn expected_count(&mut self, field: &'static str, want: u64) -> Result<u64, FileError> {
        let count = self.u64(field)?;
        if count != want {
            return Err(invalid(
                format!("{field} length"),
                format!("{count}, but the header and parent level imply {want}"),
            ));
        }
        Ok(count)
    }

    /// Reads the trailer, checks it against the hash of everything read, and checks nothing follows.
    fn finish(mut self) -> Result<(), FileError> {
        let computed = self.hasher.finalize();
        let mut stored = [0u8; 32];
        read_field(&mut self.inner, &mut stored, "hash")?;
        if computed.as_bytes() != &stored {
            return Err(FileError::HashMismatch);
        }
        let mut probe = [0u8; 1];
        loop {
            return match self.inner.read(&mut probe) {
                Ok(0) => Ok(()),
                Ok(_) => Err(FileError::TrailingBytes),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(source) => Err(FileError::Io {
                    field: "trailer",
                    source,
                }),
            };
        }
    }
}

fn read_field(r: &mut impl Read, buf: &mut [u8], field: &'static str) -> Result<(), FileError> {
    r.read_exact(buf).map_err(|source| match source.kind() {
        io::ErrorKind::UnexpectedEof => FileError::Truncated { field },
        _ => FileError::Io { field, source },
    })
}
