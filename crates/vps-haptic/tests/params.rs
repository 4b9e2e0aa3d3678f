//! Parameter loading, validation and the derived default gains.

use vps_haptic::params::ROTATIONAL_COUPLING_FACTOR;
use vps_haptic::stability::STABILITY_MARGIN;
use vps_haptic::{HapticParams, ParamsError};

fn example_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/haptic.toml")
}

#[test]
fn example_file_holds_the_defaults() {
    let p = HapticParams::from_file(example_path()).expect("configs/haptic.toml loads");
    assert_eq!(p, HapticParams::default());
}

/// The example documents the derived gains; the numbers quoted there must be the computed ones.
#[test]
fn example_file_quotes_the_derived_gains() {
    let text = std::fs::read_to_string(example_path()).unwrap();
    let g = HapticParams::default().gains();
    for (key, value) in [
        ("inertia", g.inertia),
        ("k_ff", g.k_ff),
        ("k_t", g.k_t),
        ("k_r", g.k_r),
        ("b_t", g.b_t),
        ("b_r", g.b_r),
    ] {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("# {key} = ")))
            .unwrap_or_else(|| panic!("no commented `{key}` line"));
        let quoted: f64 = line.rsplit(' ').next().unwrap().parse().unwrap();
        assert!(
            (quoted - value).abs() <= 1e-3 * value,
            "{key}: quoted {quoted}, computed {value}"
        );
    }
}

#[test]
fn default_gains_sit_at_the_stated_margin() {
    let p = HapticParams::default();
    let g = p.gains();
    let s = p.stability();
    // k_T is derived for the margin with the equal-frequency k_R; the default k_R is twice that
    // (ROTATIONAL_COUPLING_FACTOR), which lifts the rotational index a little above the margin.
    let equal_frequency = HapticParams {
        k_r: Some(g.k_t * g.inertia / p.mass),
        ..p
    };
    assert!(
        (equal_frequency.stability().worst() - STABILITY_MARGIN).abs() < 1e-9,
        "{s:?}"
    );
    assert!(s.translational < s.rotational);
    assert!(s.worst() < 0.6, "{s:?}");
    // The indices quoted in docs/haptics.md, configs/haptic.toml and `StabilityIndices`.
    assert!(
        (s.rotational - 0.574).abs() < 5e-4 && (s.translational - 0.302).abs() < 5e-4,
        "{s:?}"
    );
    assert!((g.k_ff - 2.0 * g.k_t).abs() < 1e-9);
    assert!((g.inertia - 0.4 * p.mass * p.max_radius * p.max_radius).abs() < 1e-15);
    assert!((g.b_t - 2.0 * (g.k_t * p.mass).sqrt()).abs() < 1e-12);
    assert!((g.b_r - 2.0 * (g.k_r * g.inertia).sqrt()).abs() < 1e-12);
    // The numbers quoted in the docs.
    assert!(
        (g.k_t - 317.5).abs() < 0.1 && (g.k_ff - 635.0).abs() < 0.1,
        "{g:?}"
    );
    // Same margin at other masses and steps.
    for (mass, dt) in [(0.001, 0.00025), (10.0, 0.004), (0.5, 0.001)] {
        let q = HapticParams { mass, dt, ..p };
        let gq = q.gains();
        let q_equal = HapticParams {
            k_r: Some(gq.k_t * gq.inertia / mass),
            ..q
        };
        assert!((q_equal.stability().worst() - STABILITY_MARGIN).abs() < 1e-9);
        assert!(q.stability().worst() < 0.6);
    }
}

#[test]
fn explicit_gains_override_the_derived_ones() {
    let p = HapticParams::from_toml_str("k_ff = 1000.0\nb_t = 2.5\n", "test").unwrap();
    let g = p.gains();
    assert_eq!((g.k_ff, g.k_t, g.b_t), (1000.0, 500.0, 2.5));
    let p = HapticParams::from_toml_str("k_t = 100.0\ninertia = 1e-5\n", "test").unwrap();
    let g = p.gains();
    assert_eq!((g.k_t, g.k_ff, g.inertia), (100.0, 200.0, 1e-5));
    assert!((g.k_r - ROTATIONAL_COUPLING_FACTOR * 100.0 * 1e-5 / p.mass).abs() < 1e-15);
}

#[test]
fn unknown_keys_are_an_error() {
    let err = HapticParams::from_toml_str("dt = 0.001\nstifness = 3.0\n", "my.toml").unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, ParamsError::Toml { .. }));
    assert!(msg.contains("my.toml") && msg.contains("stifness"), "{msg}");
}

#[test]
fn bad_values_name_the_field() {
    let cases = [
        ("dt = 0.0", "dt"),
        ("dt = 0.5", "dt"),
        ("mass = -1.0", "mass"),
        ("mass = nan", "mass"),
        ("voxel_size = inf", "voxel_size"),
        ("k_ff = 0.0", "k_ff"),
        ("b_r = -3.0", "b_r"),
        ("inertia = 1e9", "inertia"),
        ("velocity_guard_fraction = 1.5", "velocity_guard_fraction"),
        ("contact_average_threshold = 0", "contact_average_threshold"),
        ("max_radius = 0.0", "max_radius"),
    ];
    for (text, field) in cases {
        match HapticParams::from_toml_str(text, "cfg") {
            Err(ParamsError::Invalid { field: f, .. }) => assert_eq!(f, field, "{text}"),
            other => panic!("{text}: expected Invalid({field}), got {other:?}"),
        }
    }
    let msg = HapticParams::from_toml_str("mass = -1.0", "cfg")
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("cfg") && msg.contains("mass") && msg.contains("-1"),
        "{msg}"
    );
}

#[test]
fn absurdly_small_gains_are_refused_with_their_range() {
    // k_ff = 1e-300 was accepted: the derived coupling could not move the part at all.
    for (text, field, range) in [
        ("k_ff = 1e-300", "k_ff", "[1e0, 1e9] N/m"),
        ("k_t = 1e-3", "k_t", "[1e0, 1e9] N/m"),
        ("k_r = 1e-12", "k_r", "[1e-9, 1e6] N·m/rad"),
        ("mass = 1e-300", "mass", "[1e-6, 1e4] kg"),
        ("dt = 1e-300", "dt", "[1e-5, 1e-1] s"),
    ] {
        let err = HapticParams::from_toml_str(text, "my.toml").unwrap_err();
        let msg = err.to_string();
        assert!(
            matches!(err, ParamsError::Invalid { field: f, .. } if f == field),
            "{text}: {msg}"
        );
        assert!(
            msg.contains("my.toml") && msg.contains(field) && msg.contains(range),
            "{text}: {msg}"
        );
    }
    // Every range's own ends behave as documented.
    for r in vps_haptic::params::PARAM_RANGES {
        assert!(r.admits(r.hi), "{}", r.field);
        assert!(!r.admits(r.hi * 1.0001), "{}", r.field);
        assert_eq!(r.admits(r.lo), r.lo_included, "{}", r.field);
        assert!(!r.admits(f64::NAN), "{}", r.field);
    }
}

#[test]
fn type_errors_and_missing_files_are_reported() {
    let err = HapticParams::from_toml_str("\n\ndt = \"fast\"\n", "cfg").unwrap_err();
    assert!(err.to_string().contains("line 3"), "{err}");
    let err = HapticParams::from_file("/nonexistent/haptic.toml").unwrap_err();
    assert!(
        matches!(err, ParamsError::Io { .. })
            && err.to_string().contains("/nonexistent/haptic.toml")
    );
}

#[test]
fn with_scene_sets_and_validates() {
    let p = HapticParams::default().with_scene(0.001, 0.2).unwrap();
    assert_eq!((p.voxel_size, p.max_radius), (0.001, 0.2));
    assert!(HapticParams::default().with_scene(-1.0, 0.2).is_err());
    assert!(HapticParams::default().with_scene(0.001, f64::NAN).is_err());
}

/// The device limit left the haptic parameters: an old file that still sets it is refused with a
/// message naming the new key, not silently ignored.
#[test]
fn the_old_device_limit_keys_name_their_new_place() {
    for (text, old, new) in [
        (
            "mass = 0.012\ndevice_max_force = 15.0",
            "device_max_force",
            "`max_force`",
        ),
        (
            "device_max_torque = 0.1",
            "device_max_torque",
            "`max_torque`",
        ),
    ] {
        let err = HapticParams::from_toml_str(text, "old.toml").unwrap_err();
        assert!(
            matches!(err, ParamsError::Moved { key, .. } if key == old),
            "{err:?}"
        );
        let msg = err.to_string();
        for needle in ["old.toml", old, new, "[device]"] {
            assert!(msg.contains(needle), "{needle:?} missing from {msg}");
        }
    }
}

/// The figures of docs/haptics.md "Setting the gains for your device": derived gains per mass at
/// 1 kHz, the holding force `k_T s / 2` at 5 mm, and the k_T (per kg) at which the worse stability
/// index reaches 1 when only `k_t` is given (K_ff, k_R, b_T, b_R still derived from it).
#[test]
fn device_tuning_figures_of_the_docs() {
    let s = 0.005;
    // (mass kg, k_T N/m, b_T N·s/m, holding force N at 5 mm)
    for (mass, k_t, b_t, hold) in [
        (0.012, 317.5, 3.904, 0.794),
        (0.05, 1322.9, 16.27, 3.307),
        (0.1, 2645.8, 32.53, 6.615),
        (1.0, 26458.0, 325.3, 66.15),
    ] {
        let p = HapticParams {
            mass,
            ..HapticParams::default()
        };
        let g = p.gains();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * b;
        assert!(close(g.k_t, k_t), "mass {mass}: k_t {}", g.k_t);
        assert!(close(g.b_t, b_t), "mass {mass}: b_t {}", g.b_t);
        assert!(
            close(g.k_t * s / 2.0, hold),
            "mass {mass}: hold {}",
            g.k_t * s / 2.0
        );
        // The indices do not depend on the mass when the gains are derived.
        let idx = p.stability();
        assert!((idx.rotational - 0.574).abs() < 5e-4, "{idx:?}");
    }
    // Derived k_T per kg at dt = 1 ms: 26,458 N/m per kg; the stability ceiling with only k_t
    // given: 52,094 N/m per kg (rotational index 1), 625 N/m at 12 g.
    let ceiling_per_kg = 52_094.0;
    for mass in [0.012, 0.1, 1.0] {
        let with_kt = |k_t: f64| HapticParams {
            mass,
            k_t: Some(k_t),
            ..HapticParams::default()
        };
        let below = with_kt(0.999 * ceiling_per_kg * mass).stability();
        let above = with_kt(1.001 * ceiling_per_kg * mass).stability();
        assert!(
            below.worst() < 1.0 && above.worst() > 1.0,
            "{below:?} {above:?}"
        );
        assert!(above.rotational > above.translational);
        assert!(below.translational < 0.6, "{below:?}");
    }
    assert!((0.012f64 * ceiling_per_kg - 625.1).abs() < 0.1);
    // Damping past critical raises the index: b_T at the translational limit c·dt < 2 is 2 m / dt.
    let p = HapticParams {
        b_t: Some(2.0 * 0.012 / 0.001),
        ..HapticParams::default()
    };
    assert!(p.stability().translational.is_infinite());
}
