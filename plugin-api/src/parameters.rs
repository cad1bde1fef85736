//! A plugin's parameters: the TOML table a benchmark's configuration gives it
//! (`[plugins.params]`, or the plugin's own `configs/<name>.toml`), passed as text to
//! [`crate::SlamSystem::new`]. Every plugin parses them the same way: unknown keys are errors
//! (derive with `#[serde(deny_unknown_fields)]`), missing keys take the built-in defaults
//! (`#[serde(default)]`), and what the types cannot say is checked once after parsing.

use serde::de::DeserializeOwned;

/// A plugin's parameter set.
///
/// ```ignore
/// #[derive(Deserialize, Default)]
/// #[serde(default, deny_unknown_fields)]
/// struct Config { keyframe_distance_m: f64 }
///
/// impl Parameters for Config {
///     fn check(&self) -> Result<(), String> {
///         (self.keyframe_distance_m > 0.0)
///             .then_some(())
///             .ok_or_else(|| "keyframe_distance_m must be positive".to_owned())
///     }
/// }
///
/// let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
/// ```
pub trait Parameters: DeserializeOwned {
    /// What the types cannot say (ranges, orderings); the message names the key.
    fn check(&self) -> Result<(), String> {
        Ok(())
    }

    /// Parses and checks `text`. The error is one line, `parameters: …`, naming the key.
    fn from_toml(text: &str) -> Result<Self, String> {
        let parsed: Self =
            toml::from_str(text).map_err(|e| format!("parameters: {}", e.message()))?;
        parsed.check().map_err(|e| format!("parameters: {e}"))?;
        Ok(parsed)
    }
}
