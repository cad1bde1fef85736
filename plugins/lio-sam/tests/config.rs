//! The documented parameter file must say exactly what the plugin does without one.

use lio_sam::config::Config;

#[test]
fn documented_parameters_are_the_defaults() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/lio-sam.toml");
    let text = std::fs::read_to_string(path).expect("configs/lio-sam.toml exists");
    let parsed: Config = toml::from_str(&text).expect("configs/lio-sam.toml parses");
    assert_eq!(
        parsed,
        Config::default(),
        "configs/lio-sam.toml differs from the built-in defaults"
    );
}

#[test]
fn a_misspelt_key_is_an_error_naming_it() {
    let err = toml::from_str::<Config>("[mapping]\nkeyframe_distanse_m = 2.0\n")
        .expect_err("unknown key");
    assert!(err.to_string().contains("keyframe_distanse_m"), "{err}");
}
