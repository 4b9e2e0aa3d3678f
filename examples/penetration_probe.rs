//! Diagnostic: runs the demo's session frame by frame on the sans-IO core (no threads) and logs
//! the first frames of every penetration episode (a run of frames with a point in an Interior
//! voxel): the detour it belongs to, part and handle state, the force budget, and the Interior
//! points (depth behind the force layer, whether the Interior voxel is exposed).
//!
//! `cargo run --release --example penetration_probe -- [--no-brake] [--quiet] [--exposed] [--seconds S]`
//!
//! `--seconds S` stops after S seconds of the script (`vps demo` runs the first 60 s).
//!
//! Environment: `WIDTH=4|8` voxelizes the bay at that width instead of 2 bits; `BRAKING_TORQUE=1`
//! turns the braking torque on. The summary line also gives the frames with a point deeper than
//! the 2-bit force layer (Interior, or Surface layer ≥ 1 of a wider map: the penetration figure
//! that is comparable across widths), the p99 of the device force's frame-to-frame change over
//! consecutive touching frames (N), and the part's mean and largest kinetic energy while touching (J).

use glam::{DVec3, IVec3};
use vps_device::{HandParams, HapticDevice, SimulatedHand};
use vps_haptic::{sample_all, step, HapticParams, KernelPose, PartState};
use vps_session::{BuildOptions, SessionAssets, DEFAULT_SCENE};
use vps_voxelize::ShellMethod;
use vps_voxmap::{Voxel, VoxelTree};

/// Chebyshev distance (voxels) from `ijk` to the nearest non-Interior voxel, up to `max`.
fn interior_depth(tree: &VoxelTree, ijk: IVec3, max: i32) -> i32 {
    for r in 1..=max {
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    if dx.abs().max(dy.abs()).max(dz.abs()) == r
                        && tree.get(ijk + IVec3::new(dx, dy, dz)) != Voxel::Interior
                    {
                        return r;
                    }
                }
            }
        }
    }
    max + 1
}

/// True when an Interior voxel has a Free or Proximity 26-neighbour (not behind the force layer).
fn exposed(tree: &VoxelTree, ijk: IVec3) -> bool {
    (-1..=1).any(|dz| {
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                matches!(
                    tree.get(ijk + IVec3::new(dx, dy, dz)),
                    Voxel::Free | Voxel::Proximity
                )
            })
        })
    })
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let braking = !args.iter().any(|a| a == "--no-brake");
    let quiet = args.iter().any(|a| a == "--quiet");
    let seconds: f64 = match args.iter().position(|a| a == "--seconds") {
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| anyhow::anyhow!("--seconds needs a number"))?,
        None => f64::INFINITY,
    };
    let s = 0.005;
    let mut scene = SessionAssets::open(
        DEFAULT_SCENE,
        &BuildOptions {
            voxel_size: Some(s),
            shell_method: Some(ShellMethod::VoxelCentres),
            ..BuildOptions::default()
        },
    )?;
    if std::env::var("DROP_HANDLE").is_ok() {
        let mut shell = scene.shell.points().clone();
        let keep: Vec<bool> = shell
            .points
            .iter()
            .map(|p| !(p.x < -0.024 && p.y.abs() < 0.005))
            .collect();
        let mut k = keep.iter();
        shell.normals.retain(|_| *k.next().unwrap());
        let mut k = keep.iter();
        shell.points.retain(|_| *k.next().unwrap());
        scene.shell = vps_session::PartShell::new(shell);
        println!("dropped handle: {} points left", scene.shell.len());
    }
    let width = match std::env::var("WIDTH").ok().as_deref() {
        Some("4") => vps_voxmap::VoxelWidth::Four,
        Some("8") => vps_voxmap::VoxelWidth::Eight,
        _ => vps_voxmap::VoxelWidth::Two,
    };
    if width != vps_voxmap::VoxelWidth::Two {
        let opts = vps_voxelize::VoxelizeOptions {
            voxel_size: s,
            width,
            ..vps_voxelize::VoxelizeOptions::default()
        };
        let bay = vps_mesh::builtin::aircraft_bay();
        let (tree, _) = vps_voxelize::voxelize_tree(
            std::slice::from_ref(&bay),
            &opts,
            vps_voxmap::TreeConfig::default(),
        )?;
        scene.tree = std::sync::Arc::new(tree);
    }
    let braking_torque = std::env::var("BRAKING_TORQUE").is_ok_and(|v| v == "1");
    let tree = &scene.tree;
    let spec = *tree.spec();
    if args.iter().any(|a| a == "--exposed") {
        let (mut interior, mut exposed_count) = (0u64, 0u64);
        for k in 0..spec.dims[2] as i32 {
            for j in 0..spec.dims[1] as i32 {
                for i in 0..spec.dims[0] as i32 {
                    let ijk = IVec3::new(i, j, k);
                    if tree.get(ijk) == Voxel::Interior {
                        interior += 1;
                        exposed_count += exposed(tree, ijk) as u64;
                    }
                }
            }
        }
        println!(
            "interior voxels {interior}, exposed (26-adjacent to Free/Proximity) {exposed_count}"
        );
    }
    let kr_scale: f64 = std::env::var("KR_SCALE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1.0);
    let base = HapticParams::default().with_scene(s, scene.shell.points().max_radius())?;
    let params = HapticParams {
        k_r: Some(base.gains().k_r * kr_scale),
        braking,
        braking_torque,
        ..HapticParams::default()
    }
    .with_scene(s, scene.shell.points().max_radius())?;
    let g = params.gains();
    let si = params.stability();
    println!(
        "stability index: translational {:.3}, rotational {:.3}",
        si.translational, si.rotational
    );
    println!(
        "m {} kg, k_T {:.1} N/m, K_ff {:.1} N/m, k_R {:.3e}, clamp F {:.3} N, clamp T {:.3e} N·m, r_max {:.4} m, I {:.3e}",
        params.mass,
        g.k_t,
        g.k_ff,
        g.k_r,
        g.k_t * s / 2.0,
        g.k_r * s / 2.0 / params.max_radius,
        params.max_radius,
        g.inertia
    );
    let (mut lo, mut hi) = (glam::Vec3::splat(1.0), glam::Vec3::splat(-1.0));
    for p in &scene.shell.points().points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    println!(
        "shell {} points, body bounds {lo:.4?} .. {hi:.4?}",
        scene.shell.len()
    );
    let script = scene.script()?;
    let frames = (script.duration().min(seconds) / params.dt).round() as u64;
    let shell = scene.shell.classed();
    let (start, q0) = script.sample(0.0);
    let trace: (u64, u64, u64) = std::env::var("TRACE")
        .ok()
        .and_then(|v| {
            let f: Vec<u64> = v.split(',').filter_map(|x| x.parse().ok()).collect();
            (f.len() == 3).then(|| (f[0], f[1], f[2]))
        })
        .unwrap_or((0, 0, 1));
    let mut hand = SimulatedHand::new(script.clone(), HandParams::default())?;
    let mut state = PartState::at_rest(start, q0);
    let (mut touching, mut penetrating, mut episodes) = (0u64, 0u64, 0u64);
    let mut in_episode = 0u64;
    let mut max_depth = 0;
    let mut exposed_hits = 0u64;
    let (mut deep, mut jumps, mut last_force) = (0u64, Vec::<f64>::new(), None::<DVec3>);
    let (mut ke_sum, mut ke_max) = (0.0f64, 0.0f64);
    for frame in 0..frames {
        let t = frame as f64 * params.dt;
        let handle = hand.read(t)?;
        let pose = KernelPose::from_state(&state);
        let sums = sample_all(tree.as_ref(), &shell, &pose);
        let out = step(&params, &state, &handle, &sums);
        if (trace.0..trace.1).contains(&frame) && frame % trace.2 == 0 {
            let (target, _) = script.sample(t);
            let (ax, ang) = state.orientation.to_axis_angle();
            println!(
                "tr {frame} tgt-h {:.4?} h-x {:.4?} v {:.3?} w {:.2?} rot {:.2?}*{ang:.2} surf {} cont {} int {} appr {} Fc {:.2?} Fs {:.2?} Fb {:.2?} Tc {:.2e} Ts {:.2e}",
                target - handle.position, handle.position - state.position, state.linear_velocity, state.angular_velocity, ax,
                sums.surface, sums.contacts, sums.interior, sums.approaching, out.contact_wrench.force, out.coupling_wrench.force, out.brake_wrench.force,
                out.contact_wrench.torque.length(), out.coupling_wrench.torque.length()
            );
        }
        touching += out.touching as u64;
        penetrating += out.penetrating as u64;
        if out.touching {
            let g = params.gains();
            let ke = 0.5 * params.mass * state.linear_velocity.length_squared()
                + 0.5 * g.inertia * state.angular_velocity.length_squared();
            ke_sum += ke;
            ke_max = ke_max.max(ke);
            if let Some(f) = last_force {
                jumps.push((out.device_wrench.force - f).length());
            }
            last_force = Some(out.device_wrench.force);
            let r = pose.rotation.as_dmat3();
            deep += scene.shell.points().points.iter().any(|p| {
                let v = tree.get_layered(spec.index_of(r * p.as_dvec3() + state.position));
                v.kind == Voxel::Interior || (v.kind == Voxel::Surface && v.layer >= 1)
            }) as u64;
        } else {
            last_force = None;
        }
        if out.penetrating {
            in_episode += 1;
            if in_episode == 1 {
                episodes += 1;
            }
            // Interior points.
            let r = pose.rotation.as_dmat3();
            let mut detail = Vec::new();
            let shell = scene.shell.points();
            for (i, (p, n)) in shell.points.iter().zip(&shell.normals).enumerate() {
                let world = r * p.as_dvec3() + state.position;
                let ijk = spec.index_of(world);
                if tree.get(ijk) == Voxel::Interior {
                    let d = interior_depth(tree, ijk, 4);
                    max_depth = max_depth.max(d);
                    let e = exposed(tree, ijk);
                    exposed_hits += e as u64;
                    detail.push((i, *p, r * n.as_dvec3(), d, e, world - spec.center_of(ijk)));
                }
            }
            if !quiet && in_episode <= 2 {
                let (target, _) = script.sample(t);
                let off = target - DVec3::new(target.x, 1.0, 0.75);
                println!(
                    "ep {episodes} frame {frame} t {t:.3}: target off-corridor {:.3?}; handle-part {:.4?} |{:.4}|; v {:.3?} |{:.3}|, w {:.2?}",
                    off,
                    handle.position - state.position,
                    (handle.position - state.position).length(),
                    state.linear_velocity,
                    state.linear_velocity.length(),
                    state.angular_velocity
                );
                println!(
                    "   surf {} contacts {} interior {} approaching {}; Fc {:.3?} Fs {:.3?} |{:.3}| Fb {:.3?} Tc {:.2e} Ts {:.2e}",
                    sums.surface, sums.contacts, sums.interior, sums.approaching,
                    out.contact_wrench.force, out.coupling_wrench.force, out.coupling_wrench.force.length(),
                    out.brake_wrench.force, out.contact_wrench.torque.length(), out.coupling_wrench.torque.length()
                );
                for (i, p, n, d, e, rel) in detail.iter().take(4) {
                    let vp = state.linear_velocity + state.angular_velocity.cross(r * p.as_dvec3());
                    let opp = shell
                        .points
                        .iter()
                        .zip(&shell.normals)
                        .filter(|(q, _)| (**q - *p).length() < 1.5 * s as f32 && **q != *p)
                        .map(|(_, m)| m.dot(shell.normals[*i]))
                        .fold(1.0f32, f32::min);
                    println!(
                        "   pt {i} body {:.4?} worldN {:.2?} V.N {:.3} thin(min n.n') {opp:.2} depth {d} vox exposed {e} pos-in-voxel {:.4?}",
                        p, n, vp.dot(*n), rel
                    );
                }
            }
        } else {
            if in_episode > 0 {
                println!("   episode {episodes} ended after {in_episode} frames at t {t:.3}");
            }
            in_episode = 0;
        }
        hand.write(&out.device_wrench)?;
        state = out.next_state;
    }
    jumps.sort_by(f64::total_cmp);
    let p99 = jumps
        .get((jumps.len() as f64 * 0.99).ceil() as usize)
        .or(jumps.last())
        .copied()
        .unwrap_or(0.0);
    println!(
        "braking {braking}, braking torque {braking_torque}, {}-bit: frames {frames}, touching {touching}, penetrating {penetrating}, PR {:.2e}, episodes {episodes}, max interior depth {max_depth}, exposed-voxel hits {exposed_hits}; beyond the 2-bit force layer {deep} ({:.2e}); p99 |dF| {p99:.4} N; KE mean {:.3e} J max {:.3e} J",
        width.bits(),
        penetrating as f64 / touching.max(1) as f64,
        deep as f64 / touching.max(1) as f64,
        ke_sum / touching.max(1) as f64,
        ke_max
    );
    Ok(())
}
