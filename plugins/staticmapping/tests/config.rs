//! The documented parameter file must say exactly what the plugin does without one, and a
//! bad value must be refused with a message naming it.

use staticmapping::config::Config;

#[test]
fn documented_parameters_are_the_defaults() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/staticmapping.toml"
    );
    let text = std::fs::read_to_string(path).expect("configs/staticmapping.toml exists");
    let parsed = Config::parse(&text).expect("configs/staticmapping.toml parses");
    assert_eq!(
        parsed,
        Config::default(),
        "configs/staticmapping.toml differs from the built-in defaults"
    );
}

#[test]
fn a_misspelt_key_is_an_error_naming_it() {
    let err = Config::parse("[submap]\nframe_cout = 3\n").expect_err("unknown key");
    assert!(err.contains("frame_cout"), "{err}");
}

#[test]
fn bad_values_are_refused() {
    for (text, names) in [
        ("[input]\nsampling_rate = 0.0\n", "sampling_rate"),
        ("[input]\nmin_range_m = 80.0\n", "min_range_m"),
        (
            "[front_end]\naccumulate_cloud_num = 181\n",
            "accumulate_cloud_num",
        ),
        ("[submap]\nframe_count = 0\n", "frame_count"),
    ] {
        let err = Config::parse(text).expect_err(text);
        assert!(err.contains(names), "{text}: {err}");
    }
}
