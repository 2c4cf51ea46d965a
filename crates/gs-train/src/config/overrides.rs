//! Settings by key: every field of [`TrainConfig`] is reachable as a dotted key of its JSON
//! form (`weights.lambda_p`, `densify.grad_threshold`, `losses.features`, `ncc`), so a flag
//! (`vagsl train --set KEY=VALUE`), a configuration file and a library caller all change the
//! one configuration type, and a wrong key or type is named.

use super::TrainConfig;
use crate::error::{Result, TrainError};
use serde_json::Value;

fn bad(m: String) -> TrainError {
    TrainError::InvalidConfig(m)
}

/// The leaves of a JSON object as (dotted key, value), in document order.
fn leaves(prefix: &str, v: &Value, out: &mut Vec<(String, Value)>) {
    match v {
        Value::Object(map) => {
            for (k, x) in map {
                let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                leaves(&key, x, out);
            }
        }
        other => out.push((prefix.to_string(), other.clone())),
    }
}

/// Sets `key` (dotted) in `root` to `value`; unknown keys and tables are errors naming them.
fn set(root: &mut Value, key: &str, value: Value) -> Result<()> {
    let mut node = root;
    let parts: Vec<&str> = key.split('.').collect();
    for (i, part) in parts.iter().enumerate() {
        let at = parts[..i].join(".");
        let map = node.as_object_mut().ok_or_else(|| bad(format!("'{at}' is a value, not a table: no key '{key}'")))?;
        if !map.contains_key(*part) {
            let mut valid: Vec<&str> = map.keys().map(String::as_str).collect();
            valid.sort_unstable();
            let level = if at.is_empty() { String::from("the configuration") } else { format!("'{at}'") };
            return Err(bad(format!("unknown setting '{key}': {level} has {}", valid.join(", "))));
        }
        node = map.get_mut(*part).expect("checked");
    }
    if node.is_object() && !value.is_object() {
        return Err(bad(format!("'{key}' is a table; set its keys ({key}.…)")));
    }
    *node = value;
    Ok(())
}

impl TrainConfig {
    /// This configuration with `key` set to `value` (the JSON value of the field). A wrong key
    /// or a value of the wrong type is an error naming the key; ranges are checked by
    /// [`TrainConfig::validate`].
    pub fn with_setting(&self, key: &str, value: Value) -> Result<Self> {
        let mut root = serde_json::to_value(self).map_err(|e| bad(format!("cannot serialise the configuration: {e}")))?;
        let shown = value.to_string();
        set(&mut root, key, value)?;
        serde_json::from_value(root).map_err(|e| bad(format!("{key} = {shown}: {e}")))
    }

    /// [`TrainConfig::with_setting`] of a `KEY=VALUE` text: the value is read as JSON
    /// (`0.2`, `false`, `[0,0,0]`), else taken as a string (`ncc=plain`).
    pub fn with_assignment(&self, assignment: &str) -> Result<Self> {
        let (key, text) = assignment
            .split_once('=')
            .ok_or_else(|| bad(format!("'{assignment}' is not KEY=VALUE (e.g. weights.lambda_p=0.2)")))?;
        let value = serde_json::from_str(text.trim()).unwrap_or_else(|_| Value::String(text.trim().to_string()));
        if key.trim() == "preset" {
            // The preset picks the base values; setting it afterwards would only relabel them.
            return Err(bad(format!(
                "preset is not a setting: it picks the values every other setting starts from, so '{assignment}' would only relabel this run's values; use --preset {}",
                text.trim()
            )));
        }
        self.with_setting(key.trim(), value)
    }

    /// This configuration with every key of `overlay` (a partial configuration: a JSON object
    /// whose tables may be partial) set, in document order.
    pub fn with_overlay(&self, overlay: &Value) -> Result<Self> {
        if !overlay.is_object() {
            return Err(bad("a configuration file must hold a table of settings".into()));
        }
        let mut pairs = Vec::new();
        leaves("", overlay, &mut pairs);
        pairs.into_iter().try_fold(self.clone(), |c, (k, v)| c.with_setting(&k, v))
    }

    /// Every setting as (dotted key, JSON value), for listing and comparing configurations.
    pub fn settings(&self) -> Vec<(String, Value)> {
        let mut out = Vec::new();
        leaves("", &serde_json::to_value(self).expect("a configuration serialises"), &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn settings_reach_every_field_and_name_bad_keys() {
        let c = TrainConfig::default();
        let d = c.with_assignment("weights.lambda_p=0.2").unwrap().with_assignment("ncc=plain").unwrap();
        assert_eq!((d.weights.lambda_p, d.ncc), (0.2, gs_mvs::NccMode::Plain));
        let d = c.with_assignment("losses.features=false").unwrap().with_assignment("densify.grad_threshold = 3e-4").unwrap();
        assert!(!d.losses.features && d.densify.grad_threshold == 3e-4);
        let e = c.with_assignment("weights.lambda_q=1").unwrap_err().to_string();
        assert!(e.contains("weights.lambda_q") && e.contains("lambda_p"), "{e}");
        let e = c.with_assignment("weights.lambda_p=high").unwrap_err().to_string();
        assert!(e.contains("weights.lambda_p") && e.contains("f32"), "{e}");
        assert!(c.with_assignment("weights=1").unwrap_err().to_string().contains("is a table"));
        assert!(c.with_assignment("lambda_p").is_err());
        assert!(c.with_assignment("preset=fast").unwrap_err().to_string().contains("--preset fast"));
        // Every leaf key round-trips through the setter.
        for (k, v) in c.settings() {
            assert_eq!(c.with_setting(&k, v).unwrap(), c, "{k}");
        }
    }

    #[test]
    fn a_partial_overlay_changes_only_its_keys() {
        let c = TrainConfig::default();
        let d = c.with_overlay(&json!({ "weights": { "lambda_f": 0.5 }, "seed": 9 })).unwrap();
        assert_eq!(d, TrainConfig { seed: 9, weights: super::super::LossWeights { lambda_f: 0.5, ..c.weights }, ..c.clone() });
        // A whole configuration reproduces itself from any base.
        let fast = TrainConfig::preset(super::super::Preset::Fast);
        assert_eq!(c.with_overlay(&serde_json::to_value(&fast).unwrap()).unwrap(), fast);
    }
}
