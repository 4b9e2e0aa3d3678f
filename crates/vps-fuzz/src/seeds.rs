//! Seed corpora: real, valid inputs of every format, produced by the project's own writers (or, for
//! the mesh formats, by the small writers here), so mutations start from bytes the parsers accept.

use glam::{DQuat, DVec3, Mat3, Vec3};
use std::path::Path;
use vps_cluster::protocol::{AssetsIdentity, FrameReply, FrameRequest, JoinMessage};
use vps_device::trace::{write_trace, TraceRecorder};
use vps_haptic::{HandleSample, KernelPose, PartialSums, Wrench};
use vps_input::bridge::protocol::{Datagram, Message, MAX_DATAGRAM};
use vps_mesh::TriMesh;
use vps_voxelize::{point_shell, voxelize_tree, ShellMethod, VoxelizeOptions};
use vps_voxmap::{TreeConfig, VoxelWidth};

/// The meshes the mesh seeds are written from: the built-in 0.1 m box (12 triangles) and a
/// tetrahedron.
pub fn seed_meshes() -> Vec<TriMesh> {
    let cube = vps_mesh::builtin::by_name("box").expect("built-in box");
    let tetra = TriMesh {
        vertices: vec![
            DVec3::ZERO,
            DVec3::new(0.1, 0.0, 0.0),
            DVec3::new(0.0, 0.1, 0.0),
            DVec3::new(0.0, 0.0, 0.1),
        ],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    };
    vec![cube, tetra]
}

/// OBJ seeds: plain `v`/`f`, and a variant with normals, texture coordinates, `f a/b/c` references,
/// negative (relative) indices, comments, groups and a quad.
pub fn obj() -> Vec<Vec<u8>> {
    let mut out: Vec<Vec<u8>> = seed_meshes()
        .iter()
        .map(|m| {
            let mut s = String::from("# vps fuzz seed\no part\n");
            for v in &m.vertices {
                s += &format!("v {} {} {}\n", v.x, v.y, v.z);
            }
            for t in &m.triangles {
                s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
            }
            s.into_bytes()
        })
        .collect();
    out.push(
        b"mtllib none.mtl\ng quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\n\
          vt 1 1\nvn 0 0 1\ns off\nf 1/1/1 2/2/1 3/3/1 4/1/1\nf -5//1 -4//1 -1//1\nusemtl x\n\
          f 2/2 3/3 5/1\n"
            .to_vec(),
    );
    out
}

/// STL seeds: ASCII and binary encodings of every seed mesh.
pub fn stl() -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for m in seed_meshes() {
        let mut s = String::from("solid part\n");
        for i in 0..m.triangles.len() {
            let [a, b, c] = m.triangle(i);
            let n = (b - a).cross(c - a).normalize_or_zero();
            s += &format!("  facet normal {} {} {}\n    outer loop\n", n.x, n.y, n.z);
            for p in [a, b, c] {
                s += &format!("      vertex {} {} {}\n", p.x, p.y, p.z);
            }
            s += "    endloop\n  endfacet\n";
        }
        s += "endsolid part\n";
        out.push(s.into_bytes());

        let mut bin = vec![0u8; 80];
        bin[..14].copy_from_slice(b"vps fuzz seed ");
        bin.extend_from_slice(&(m.triangles.len() as u32).to_le_bytes());
        for i in 0..m.triangles.len() {
            let [a, b, c] = m.triangle(i);
            let n = (b - a).cross(c - a).normalize_or_zero();
            for p in [n, a, b, c] {
                for x in p.as_vec3().to_array() {
                    bin.extend_from_slice(&x.to_le_bytes());
                }
            }
            bin.extend_from_slice(&0u16.to_le_bytes());
        }
        out.push(bin);
    }
    out
}

/// STEP seeds: public test files (assets/step/README.md): a cube (AP203), a solid with a void,
/// B-spline faces, a two-solid file in metres, an assembly with placements.
pub fn step() -> Vec<Vec<u8>> {
    [
        include_bytes!("../../../assets/step/box_ap203.step").as_slice(),
        include_bytes!("../../../assets/step/hollow_box_ap214_is.step"),
        include_bytes!("../../../assets/step/tapered_box_ap214_is.step"),
        include_bytes!("../../../assets/step/red_cube_blue_cylinder.step"),
        include_bytes!("../../../assets/step/assembly_ap214_is.step"),
    ]
    .iter()
    .map(|b| b.to_vec())
    .collect()
}

/// PLY seeds: ASCII (`vertex_indices`, with a quad and an extra property) and binary
/// little-endian (`vertex_index`, float and double coordinates).
pub fn ply() -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for m in seed_meshes() {
        let mut s = format!(
            "ply\nformat ascii 1.0\ncomment vps fuzz seed\nelement vertex {}\nproperty float x\n\
             property float y\nproperty float z\nproperty uchar red\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            m.vertices.len(),
            m.triangles.len()
        );
        for v in &m.vertices {
            s += &format!("{} {} {} 7\n", v.x, v.y, v.z);
        }
        for t in &m.triangles {
            s += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
        }
        out.push(s.into_bytes());

        let mut bin = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\n\
             property double y\nproperty double z\nelement face {}\n\
             property list uchar uint vertex_index\nend_header\n",
            m.vertices.len(),
            m.triangles.len()
        )
        .into_bytes();
        for v in &m.vertices {
            for x in v.to_array() {
                bin.extend_from_slice(&x.to_le_bytes());
            }
        }
        for t in &m.triangles {
            bin.push(3);
            for i in t {
                bin.extend_from_slice(&i.to_le_bytes());
            }
        }
        out.push(bin);
    }
    out.push(
        b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
          property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
          0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"
            .to_vec(),
    );
    out
}

/// `.vmap` seeds: the box voxelized at 2 cm as 2-, 4- and 8-bit trees (file versions 1 and 2),
/// with the default tree shape and a small uniform one; the 4-bit one again with a signed-distance
/// band of stand-off 2.5 mm (version 3, what the `distance` force model caches).
pub fn vmap() -> Vec<Vec<u8>> {
    let cube = vps_mesh::builtin::by_name("box").expect("built-in box");
    let mut out = Vec::new();
    for (width, config, band) in [
        (VoxelWidth::Two, TreeConfig::default(), false),
        (VoxelWidth::Two, TreeConfig::uniform(2), false),
        (VoxelWidth::Four, TreeConfig::uniform(2), false),
        (VoxelWidth::Eight, TreeConfig::uniform(2), false),
        (VoxelWidth::Four, TreeConfig::default(), true),
    ] {
        let opts = VoxelizeOptions {
            voxel_size: 0.02,
            width,
            ..VoxelizeOptions::default()
        };
        let objects = std::slice::from_ref(&cube);
        let (mut tree, _) = voxelize_tree(objects, &opts, config).expect("voxelizing the seed box");
        if band {
            let band = vps_voxelize::distance::distance_band(&tree, objects, 0.0025, 1 << 30)
                .expect("the seed box's distance band");
            tree = tree.with_distance_band(band);
        }
        let mut bytes = Vec::new();
        vps_voxmap::file::write_voxmap(&tree, &mut bytes).expect("encoding a seed voxmap");
        out.push(bytes);
    }
    out.push(uniform_vmap([1024, 1024, 1024], 0.01, 1));
    out
}

/// A valid `.vmap` (version 1, 2-bit, the default 512-tree) whose every root slot is a tile of
/// `code` (0 Free, 1 Interior, 2 Surface, 3 Proximity; [`vps_voxmap::Voxel`]'s values): a map of
/// `dims` voxels of `voxel_size` (m) in a few bytes per 512³ voxels, with a correct hash. Such a
/// file is legal, and small however large its grid (8192³ voxels, 2^39, is a 16 KiB file).
pub fn uniform_vmap(dims: [u32; 3], voxel_size: f64, code: u8) -> Vec<u8> {
    const ROOT_EXTENT: u64 = 512;
    let mut b = Vec::new();
    b.extend_from_slice(&vps_voxmap::file::VOXMAP_MAGIC);
    b.extend_from_slice(&vps_voxmap::file::VOXMAP_VERSION_2BIT.to_le_bytes());
    b.extend_from_slice(&voxel_size.to_le_bytes());
    for _ in 0..3 {
        b.extend_from_slice(&0f64.to_le_bytes());
    }
    for d in dims {
        b.extend_from_slice(&d.to_le_bytes());
    }
    b.extend_from_slice(&[3, 3, 3]);
    let root_slots: u64 = dims
        .iter()
        .map(|&d| u64::from(d).div_ceil(ROOT_EXTENT))
        .product();
    b.extend_from_slice(&root_slots.to_le_bytes());
    for _ in 0..root_slots {
        b.extend_from_slice(&((1u32 << 31) | u32::from(code)).to_le_bytes());
    }
    // Empty upper, lower and leaf arenas.
    for _ in 0..3 {
        b.extend_from_slice(&0u64.to_le_bytes());
    }
    let hash = blake3::hash(&b);
    b.extend_from_slice(hash.as_bytes());
    b
}

/// `.vshell` seeds: the tetrahedron's point shells at 2 cm, by both methods.
pub fn vshell() -> Vec<Vec<u8>> {
    let tetra = seed_meshes().pop().expect("tetrahedron");
    [ShellMethod::VoxelCentres, ShellMethod::ExactSurface]
        .into_iter()
        .map(|method| {
            let shell = point_shell(&tetra, 0.02, method).expect("seed shell");
            let mut bytes = Vec::new();
            vps_voxmap::file::write_shell(&shell, &mut bytes).expect("encoding a seed shell");
            bytes
        })
        .collect()
}

/// Haptic parameter seeds: the shipped `configs/haptic.toml`, the defaults as serialised, and a
/// file setting the gains explicitly.
pub fn haptic_toml() -> Vec<Vec<u8>> {
    let defaults = toml::to_string(&vps_haptic::HapticParams::default()).expect("defaults");
    vec![
        include_bytes!("../../../configs/haptic.toml").to_vec(),
        defaults.into_bytes(),
        b"dt = 0.001\nmass = 0.012\ninertia = 2e-5\nvoxel_size = 0.005\nmax_radius = 0.05\n"
            .to_vec(),
    ]
}

/// Sweep file seeds: the committed `configs/sweep.toml`, and one using every key (each run's own
/// sizes, widths, methods and length, and the reference budget).
pub fn sweep_toml() -> Vec<Vec<u8>> {
    vec![
        include_bytes!("../../../configs/sweep.toml").to_vec(),
        br#"voxel_sizes_mm = [10.0, 2.5]
methods = ["centres"]
widths = [2]
reference_points_per_frame = 64
[[run]]
scene = "scenes/bay-teapot.toml"
voxel_sizes_mm = [5.0, 1.25]
widths = [4, 8]
methods = ["exact", "centres"]
seconds = 2.5
[[run]]
scene = "scenes/rig-teapot.toml"
"#
        .to_vec(),
    ]
}

/// A scene of two `[[part]]`s, each with its own hand and a bridge device with a mapping.
const TWO_PARTS_ON_BRIDGES: &str = r#"[[static]]
source = "builtin:box"
[[part]]
name = "tool"
source = "builtin:cylinder"
grip = [0.0, 0.0, 0.05]
[part.hand]
waypoints = [[0.0, 0.0, 0.2]]
[part.device]
kind = "bridge:127.0.0.1:7700"
mapping = { scale = 2.0, rotate_deg = [90.0, 0.0, 0.0] }
[[part]]
name = "part"
source = "builtin:sphere"
scale = [0.5, 0.5, 1.0]
[part.hand]
waypoints = [[0.1, 0.0, 0.2], [0.0, 0.0, 0.2]]
speed = 0.05
[part.device]
kind = "bridge:127.0.0.1:7701"
pose_timeout_ms = 100
"#;

/// Scene file seeds: the committed scene files (`configs/scenes/*.toml`, the worked examples in
/// `assets/scenes/`), one using every optional section (`[hand]`, `[workspace]`, inline
/// `[haptic]`, a bridge `[device]` with its mapping and timeout, lengths as strings), and one of
/// two `[[part]]`s each on its own bridge.
pub fn scene_toml() -> Vec<Vec<u8>> {
    let every_section = r#"name = "every-section"
[part]
source = "builtin:teapot"
units = "cm"
rotate_deg = [90, 0, 45]
grip = [0.0, 0.0, 0.01]
[[static]]
source = "builtin:box"
scale = [2.0, 2.0, 0.5]
translate = [0.0, 0.0, -0.1]
[[static]]
source = "builtin:sphere"
units = "mm"
[hand]
waypoints = [[0.0, 0.0, 0.1], [0.05, 0.0, 0.02], [0.1, 0.0, 0.1]]
speed = 0.08
hold_s = 0.4
[voxels]
voxel_size = "4mm"
voxel_width = 4
offset_layers = 3
shell_method = "exact"
braking = true
[workspace]
min = [-0.2, -0.2, -0.2]
max = [0.2, 0.2, 0.2]
[haptic]
mass = 0.5
k_ff = 2000.0
device_max_force = 4.0
"#;
    let device = bridge_device_section("127.0.0.1:7700", 100, 5.0, [90, 0, 0], [0.05, 0.0, 0.0]);
    vec![
        include_bytes!("../../../configs/scenes/bay-teapot.toml").to_vec(),
        include_bytes!("../../../configs/scenes/rig-teapot.toml").to_vec(),
        include_bytes!("../../../assets/scenes/bracket-in-bay.toml").to_vec(),
        include_bytes!("../../../assets/scenes/two-hands.toml").to_vec(),
        format!("{every_section}{device}force_scale = 0.5\n").into_bytes(),
        TWO_PARTS_ON_BRIDGES.as_bytes().to_vec(),
    ]
}

/// The `[device]` section of a scene file whose device is the UDP bridge on `addr`, held after
/// `pose_timeout_ms` (ms) of silence, with a `[device.mapping]`: `scale` scene metres per device
/// metre, `rotate_deg` the device axes' rotation into the scene's (degrees, X then Y then Z),
/// `offset` the scene position of the device origin (m). Ends with a newline, so that more
/// `[device.mapping]` keys may follow. The scene-file seed is written with it, and so is the
/// mapped-bridge scene of the bridge tests (`tests/bridge_clients.rs`).
pub fn bridge_device_section(
    addr: &str,
    pose_timeout_ms: u32,
    scale: f64,
    rotate_deg: [i32; 3],
    offset: [f64; 3],
) -> String {
    format!(
        "[device]\nkind = \"bridge:{addr}\"\npose_timeout_ms = {pose_timeout_ms}\n\
         [device.mapping]\nscale = {scale:?}\nrotate_deg = {rotate_deg:?}\noffset = {offset:?}\n"
    )
}

fn sample(i: u32) -> HandleSample {
    let t = f64::from(i) * 1e-3;
    HandleSample {
        position: DVec3::new(0.01 * t, -0.02, 0.3 + t),
        orientation: DQuat::from_rotation_z(t),
        linear_velocity: DVec3::new(0.01, 0.0, 1.0),
        angular_velocity: DVec3::new(0.0, 0.0, 1.0),
    }
}

/// Trace seeds: traces of 0, 1 and 6 frames, as `vps_device::trace::write_trace` writes them.
pub fn trace() -> Vec<Vec<u8>> {
    [0u32, 1, 6]
        .into_iter()
        .map(|frames| {
            let mut rec = TraceRecorder::with_capacity("sim-hand", 0.001, frames as usize);
            for i in 0..frames {
                rec.record(u64::from(i), f64::from(i) * 1e-3, sample(i))
                    .expect("seed frame");
            }
            let mut bytes = Vec::new();
            write_trace(&mut bytes, &rec.finish(), Path::new("seed.trace")).expect("seed trace");
            bytes
        })
        .collect()
}

/// Bridge seeds: a PoseIn and a WrenchOut datagram.
pub fn bridge_datagram() -> Vec<Vec<u8>> {
    let messages = [
        Message::PoseIn(sample(3)),
        Message::WrenchOut {
            wrench: Wrench {
                force: DVec3::new(0.5, -0.25, 1.0),
                torque: DVec3::new(0.0, 0.01, 0.0),
            },
            frame: 42,
        },
    ];
    messages
        .into_iter()
        .map(|message| {
            let d = Datagram {
                token: *b"0123456789abcdef",
                sequence: 7,
                message,
            };
            let mut buf = [0u8; MAX_DATAGRAM];
            let n = d.encode(&mut buf);
            buf[..n].to_vec()
        })
        .collect()
}

/// Cluster seeds: a frame request, a frame reply, and every join message.
pub fn cluster_datagram() -> Vec<Vec<u8>> {
    let pose = KernelPose {
        rotation: Mat3::IDENTITY,
        translation: Vec3::new(0.1, 0.2, 0.3),
        linear_velocity: Vec3::ZERO,
        angular_velocity: Vec3::new(0.0, 0.0, 1.0),
    };
    let mut request = [0u8; vps_cluster::protocol::REQUEST_LEN];
    let job = vps_haptic::JobTarget { shell: 1, map: 2 };
    FrameRequest {
        seq: 9,
        classes: 0b1011,
        job,
        pose,
    }
    .encode(&mut request);
    let mut reply = [0u8; vps_cluster::protocol::REPLY_LEN];
    FrameReply {
        seq: 9,
        classes: 0b1011,
        job,
        sums: PartialSums::default(),
    }
    .encode(&mut reply);
    let mut out = vec![request.to_vec(), reply.to_vec()];
    out.extend(join_messages().iter().map(JoinMessage::encode));
    out
}

/// Every join message kind, with its fields at their edges: versions 0, 1 and `u16::MAX`; a
/// welcome to the first and the last worker id, of one part and of two; an empty, a short and a
/// long reason; needs of no file, some and every bit.
fn join_messages() -> Vec<JoinMessage> {
    use vps_cluster::protocol::{AssetFile, AssetKind};
    // Each file as (kind, the byte its hash repeats, length): the scene's voxmap and shell, then
    // a second part's shell and two more voxmaps.
    let files = [
        (AssetKind::Voxmap, 1, 1 << 20),
        (AssetKind::Shell, 2, 1 << 16),
        (AssetKind::Shell, 3, 1 << 12),
        (AssetKind::Voxmap, 4, 1 << 14),
        (AssetKind::Voxmap, 5, 1 << 15),
    ];
    // The assets of `parts` parts and `class_count` classes: the first `count` files.
    let identity = |class_count, parts, count| AssetsIdentity {
        class_count,
        parts,
        files: files[..count]
            .iter()
            .map(|&(kind, byte, len)| AssetFile {
                kind,
                hash: [byte; 32],
                len,
            })
            .collect(),
    };
    let scene = identity(8, 1, 2);
    let two_parts = identity(64, 2, files.len());
    let mut all: Vec<JoinMessage> = [0, 1, u16::MAX]
        .map(|version| JoinMessage::Hello { version })
        .into();
    all.extend([0, u32::MAX].map(|worker_id| JoinMessage::Welcome {
        worker_id,
        assets: scene.clone(),
    }));
    all.push(JoinMessage::Welcome {
        worker_id: 7,
        assets: two_parts,
    });
    all.extend(
        ["", "scene mismatch", &"x".repeat(200)].map(|reason| JoinMessage::Reject {
            reason: reason.to_string(),
        }),
    );
    for files in [0, 0b1, 0b10, 0b11, 0b11111, u64::MAX] {
        all.push(JoinMessage::Need { files });
    }
    all.push(JoinMessage::Ready);
    all
}

/// Between a cache entry's map bytes and its record's text in a `cache-entry` input.
pub const CACHE_RECORD_MARKER: &[u8] = b"\n#record\n";

/// The cache entry the `cache-entry` target asks for: the built-in box voxelized at 2 cm, 2-bit,
/// the default tree (its key, grid, width and tree shape).
pub fn cache_expected() -> &'static vps_session::cache::Expected {
    static EXPECTED: std::sync::OnceLock<vps_session::cache::Expected> = std::sync::OnceLock::new();
    EXPECTED.get_or_init(|| cache_map(0.02).1)
}

/// The built-in box voxelized at `voxel_size` (m) into a cache entry: its map and what it is.
fn cache_map(voxel_size: f64) -> (vps_voxmap::VoxelTree, vps_session::cache::Expected) {
    let cube = vps_mesh::builtin::by_name("box").expect("built-in box");
    let objects = std::slice::from_ref(&cube);
    let opts = VoxelizeOptions {
        voxel_size,
        ..VoxelizeOptions::default()
    };
    let config = TreeConfig::default();
    let (tree, _) = voxelize_tree(objects, &opts, config).expect("voxelizing the seed box");
    let expected = vps_session::cache::Expected {
        key: vps_session::cache::cache_key(objects, &opts, config),
        spec: vps_voxelize::tree_grid(objects, &opts).expect("the seed box's grid"),
        width: opts.width,
        config,
        standoff_m: None,
    };
    (tree, expected)
}

/// Cache entries (`cache-entry` target): the entry asked for with its record; the same map with
/// no record and with the record of another entry; another entry's map (4 cm) with its own
/// record and with a record forged to name the key asked for; the map asked for carrying a
/// distance band (stand-off 2.5 mm) that was not asked for, with its own record.
pub fn cache_entry() -> Vec<Vec<u8>> {
    let entry = |tree: &vps_voxmap::VoxelTree, record: Option<String>| {
        let mut bytes = Vec::new();
        vps_voxmap::file::write_voxmap(tree, &mut bytes).expect("encoding a seed voxmap");
        if let Some(record) = record {
            bytes.extend_from_slice(CACHE_RECORD_MARKER);
            bytes.extend_from_slice(record.as_bytes());
        }
        bytes
    };
    let record = vps_session::cache::record_text;
    let (tree, asked) = cache_map(0.02);
    let (other, theirs) = cache_map(0.04);
    let cube = vps_mesh::builtin::by_name("box").expect("built-in box");
    let band = vps_voxelize::distance::distance_band(&tree, &[cube], 0.0025, 1 << 30)
        .expect("the seed box's distance band");
    let banded = tree.clone().with_distance_band(band);
    vec![
        entry(&tree, Some(record(&asked.key, &tree))),
        entry(&tree, None),
        entry(&tree, Some(record(&theirs.key, &other))),
        entry(&other, Some(record(&theirs.key, &other))),
        entry(&other, Some(record(&asked.key, &other))),
        entry(&banded, Some(record(&asked.key, &banded))),
    ]
}

/// Between the scene file and each mesh file in a `scene-mesh` input: the marker, the mesh
/// file's name, a line break, then its bytes (up to the next marker).
pub const SCENE_FILE_MARKER: &[u8] = b"\n#file ";

/// A `scene-mesh` input: the scene file's text, then each `(name, bytes)` mesh file after a
/// [`SCENE_FILE_MARKER`] line.
pub fn scene_bundle(scene: &str, files: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let mut out = scene.as_bytes().to_vec();
    for (name, bytes) in files {
        out.extend_from_slice(SCENE_FILE_MARKER);
        out.extend_from_slice(name.as_bytes());
        out.push(b'\n');
        out.extend_from_slice(bytes);
    }
    out
}

/// A flat `n`×`n`-vertex plate (`size` m square) as OBJ text.
fn plate_obj(n: usize, size: f64) -> Vec<u8> {
    let mut s = String::new();
    for j in 0..n {
        for i in 0..n {
            let f = size / (n - 1) as f64;
            s += &format!("v {} {} 0\n", i as f64 * f, j as f64 * f);
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i + 1;
            s += &format!(
                "f {a} {} {}\nf {a} {} {}\n",
                a + 1,
                a + n + 1,
                a + n + 1,
                a + n
            );
        }
    }
    s.into_bytes()
}

/// Scene files with their mesh files (`scene-mesh` target): a static OBJ cube 1 m across (the
/// 0.1 m box scaled) with a binary STL part; one OBJ named by twenty objects in several spellings
/// with a PLY part; a scene whose meshes are malformed (an OBJ face past its vertices) or claim
/// absurd counts (a PLY `element vertex 4294967295`, a binary STL of 4294967295 triangles in 134
/// bytes); a mesh in millimetres scaled and rotated; and 400 objects naming one 2,000-triangle
/// plate (placed copies over a 16 MiB budget).
pub fn scene_mesh() -> Vec<Vec<u8>> {
    let obj = obj();
    let stl = stl();
    let ply = ply();
    let hand = "[hand]\nwaypoints = [[0.0, 0.0, 0.3], [0.05, 0.0, 0.2]]\n";
    let cube_scene = format!(
        "name = \"mesh-refs\"\n[part]\nsource = \"part.stl\"\n[[static]]\nsource = \"cube.obj\"\n\
         scale = [10.0, 10.0, 10.0]\ntranslate = [-0.5, -0.5, -1.0]\n[voxels]\nvoxel_size = 0.05\n{hand}"
    );
    let mut twenty = String::from("[part]\nsource = \"part.ply\"\n[voxels]\nvoxel_size = 0.05\n");
    let spellings = ["cube.obj", "./cube.obj", ".//cube.obj", "cube.obj"];
    for i in 0..20 {
        twenty += &format!(
            "[[static]]\nsource = \"{}\"\nscale = [10.0, 10.0, 10.0]\ntranslate = [{}, 0, -1.0]\n",
            spellings[i % 4],
            i as f64 * 0.5
        );
    }
    twenty += hand;
    let mut huge_stl = vec![0u8; 80];
    huge_stl.extend_from_slice(&u32::MAX.to_le_bytes());
    huge_stl.extend_from_slice(&[0u8; 50]);
    let huge_ply = b"ply\nformat ascii 1.0\nelement vertex 4294967295\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\n\
        property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n3 0 1 2\n"
        .to_vec();
    let bad_scene = format!(
        "[part]\nsource = \"part.stl\"\n[[static]]\nsource = \"bad.obj\"\n[[static]]\n\
         source = \"huge.ply\"\n[[static]]\nsource = \"cube.obj\"\nscale = [10.0, 10.0, 10.0]\n{hand}"
    );
    let mm_scene = format!(
        "[part]\nsource = \"part.obj\"\nunits = \"mm\"\nrotate_deg = [90, 0, 45]\n[[static]]\n\
         source = \"cube.stl\"\nunits = \"cm\"\nscale = [20.0, 20.0, 2.0]\nrotate_deg = [0, 0, 30]\n\
         [[static]]\nsource = \"builtin:box\"\ntranslate = [0.0, 0.0, -0.2]\n\
         [voxels]\nvoxel_size = \"1cm\"\nforce_model = \"distance\"\n{hand}"
    );
    let mut plates =
        String::from("[part]\nsource = \"builtin:box\"\n[voxels]\nvoxel_size = 0.05\n");
    for i in 0..400 {
        plates += &format!(
            "[[static]]\nsource = \"plate.obj\"\ntranslate = [0, 0, {}]\n",
            i as f64 * 0.01
        );
    }
    plates += hand;
    vec![
        scene_bundle(
            &cube_scene,
            &[("cube.obj", obj[0].clone()), ("part.stl", stl[1].clone())],
        ),
        scene_bundle(
            &twenty,
            &[("cube.obj", obj[0].clone()), ("part.ply", ply[1].clone())],
        ),
        scene_bundle(
            &bad_scene,
            &[
                ("bad.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".to_vec()),
                ("huge.ply", huge_ply),
                ("cube.obj", obj[0].clone()),
                ("part.stl", huge_stl),
            ],
        ),
        scene_bundle(
            &mm_scene,
            &[("part.obj", obj[2].clone()), ("cube.stl", stl[0].clone())],
        ),
        scene_bundle(&plates, &[("plate.obj", plate_obj(32, 1.0))]),
    ]
}
