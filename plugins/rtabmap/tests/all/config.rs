//! The documented parameter file must say exactly what the plugin does without one.

use plugin_api::Parameters;
use rtabmap::config::Config;

#[test]
fn documented_parameters_are_the_defaults() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/rtabmap.toml");
    let text = std::fs::read_to_string(path).expect("configs/rtabmap.toml exists");
    let parsed = Config::from_toml(&text).expect("configs/rtabmap.toml parses");
    assert_eq!(
        parsed,
        Config::default(),
        "configs/rtabmap.toml differs from the built-in defaults"
    );
}

#[test]
fn a_misspelt_key_is_an_error_naming_it() {
    let err = Config::from_toml("[memory]\nshort_term_memmory = 5\n").expect_err("unknown key");
    assert!(err.contains("short_term_memmory"), "{err}");
    let err = Config::from_toml("odometry = \"lidar\"\n").expect_err("unknown odometry");
    assert!(err.contains("lidar"), "{err}");
    let err = Config::from_toml("[memory]\ndetection_rate_hz = 0.0\n").expect_err("zero rate");
    assert!(err.contains("detection_rate_hz"), "{err}");
}
