//! The per-part lines of a session's report in a scene of several moving parts: each part's
//! device, where it ended, the wrenches its device got and its contact with the other parts.

use serde::Serialize;
use vps_runtime::{LoopReport, PairCounts};
use vps_session::SessionAssets;

/// One moving part of a session (all of them, the first first, when the scene has several).
#[derive(Serialize)]
pub struct PartSummary {
    /// The part's name.
    pub name: String,
    /// Its device's name.
    pub device: String,
    /// Its grip's position after the last frame (m).
    pub final_position_m: [f64; 3],
    /// Its hand's position in the last frame (m), when a frame ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_hand_position_m: Option<[f64; 3]>,
    /// Its speed after the last frame (m/s).
    pub final_speed_m_per_s: f64,
    /// Wrenches written to its device (one per frame; the final zero not counted).
    pub wrenches_written: u64,
    /// Largest force magnitude written to its device (N).
    pub max_device_force_n: f64,
    /// Frames whose wrench was clamped to its device's limits.
    pub clamped_frames: u64,
    /// Frames whose step gave a non-finite value.
    pub non_finite_frames: u64,
    /// Frames where it touched another part (some point in a non-Free voxel of a pair).
    pub pair_contact_frames: u64,
    /// The other parts' force on it in the last frame (N, world frame).
    pub last_pair_force_n: [f64; 3],
    /// The other parts' torque on it in the last frame (N·m about its grip, world frame).
    pub last_pair_torque_nm: [f64; 3],
    /// Its device's own counters (a bridge's datagram counts), when it keeps any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device_counters: Option<serde_json::Value>,
}

/// Every part's summary (empty in a one-part session).
pub fn part_summaries(assets: &SessionAssets, report: &LoopReport) -> Vec<PartSummary> {
    if report.other_parts.is_empty() {
        return Vec::new();
    }
    let first = PartSummary {
        name: assets.part_name.clone(),
        device: report.device_name.clone(),
        final_position_m: report.final_state.position.to_array(),
        final_hand_position_m: report.final_handle.map(|h| h.position.to_array()),
        final_speed_m_per_s: report.final_state.linear_velocity.length(),
        wrenches_written: report.stats.frames,
        max_device_force_n: report.max_device_force,
        clamped_frames: report.stats.clamped_frames,
        non_finite_frames: report.stats.non_finite_frames,
        pair_contact_frames: report.pair_contact_frames,
        last_pair_force_n: report.last_pair_wrench.force.to_array(),
        last_pair_torque_nm: report.last_pair_wrench.torque.to_array(),
        device_counters: report.device_counters.clone(),
    };
    std::iter::once(first)
        .chain(report.other_parts.iter().map(|p| PartSummary {
            name: p.name.clone(),
            device: p.device_name.clone(),
            final_position_m: p.final_state.position.to_array(),
            final_hand_position_m: p.final_handle.map(|h| h.position.to_array()),
            final_speed_m_per_s: p.final_state.linear_velocity.length(),
            wrenches_written: p.wrenches_written,
            max_device_force_n: p.max_device_force,
            clamped_frames: p.clamped_frames,
            non_finite_frames: p.non_finite_frames,
            pair_contact_frames: p.pair_contact_frames,
            last_pair_force_n: p.last_pair_wrench.force.to_array(),
            last_pair_torque_nm: p.last_pair_wrench.torque.to_array(),
            device_counters: p.device_counters.clone(),
        }))
        .collect()
}

/// Prints the parts' lines and the pairs' counts for a person.
pub fn print_parts(parts: &[PartSummary], pairs: &PairCounts) {
    for p in parts {
        let [x, y, z] = p.final_position_m.map(crate::output::metres_4);
        let f = glam::DVec3::from_array(p.last_pair_force_n).length();
        println!(
            "part '{}' ({}): ended at [{x}, {y}, {z}] m, {} frame(s) touching another part, \
             last force from the other parts {f:.3} N, {} clamped, {} non-finite frame(s)",
            p.name, p.device, p.pair_contact_frames, p.clamped_frames, p.non_finite_frames
        );
    }
    println!(
        "pairs: {} sampled, {} skipped by the broad phase (bounding spheres apart), {} frame(s) \
         with parts touching",
        pairs.sampled, pairs.skipped, pairs.contact_frames
    );
}
