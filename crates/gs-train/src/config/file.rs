//! Configuration files (`vagsl train --config FILE`): a partial configuration in TOML or JSON,
//! or a run's own `config.json`. Parsed from bytes so that the reader can be fuzzed; the path
//! names the file in errors and its extension picks the syntax.

use super::{Preset, TrainConfig};
use crate::error::{Result, TrainError};
use serde_json::Value;
use std::path::Path;

/// What a configuration file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct SettingsFile {
    /// The training settings: the whole file, or a run configuration's "train" table.
    pub settings: Value,
    /// The whole document when the file is a run's own `config.json` (a table with both
    /// "train" and "scene"), which the caller reads as its run configuration.
    pub run: Option<Value>,
}

fn file_error(path: &Path, problem: String) -> TrainError {
    TrainError::ConfigFile { path: path.to_path_buf(), problem }
}

/// Parses a configuration file's bytes: TOML when `path` ends in `.toml`, else JSON. Text
/// that is not UTF-8, not valid in its syntax, or not a table of settings is an error naming
/// the file.
pub fn parse_settings_file(bytes: &[u8], path: &Path) -> Result<SettingsFile> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        file_error(path, format!("not UTF-8 text (byte offset {}); a configuration file is TOML or JSON text", e.valid_up_to()))
    })?;
    let value: Value = match path.extension().and_then(|e| e.to_str()) {
        Some("toml") => {
            let table: toml::Table = toml::from_str(text).map_err(|e| {
                let line = 1 + e.span().map_or(0, |s| text.as_bytes()[..s.start.min(text.len())].iter().filter(|&&b| b == b'\n').count());
                file_error(path, format!("not valid TOML at line {line}: {}", e.message().trim_end()))
            })?;
            // JSON (the settings' form) has no NaN or infinity: they would arrive as null.
            if let Some((key, v)) = non_finite(&toml::Value::Table(table.clone()), "") {
                return Err(file_error(path, format!("{key} = {v}: must be a finite number")));
            }
            serde_json::to_value(table).map_err(|e| file_error(path, format!("not a table of settings: {e}")))?
        }
        _ => serde_json::from_str(text).map_err(|e| {
            let words = gs_io::json_error_words(bytes, &e).replacen("malformed JSON", "not valid JSON (use .toml for TOML)", 1);
            file_error(path, words)
        })?,
    };
    if !value.is_object() {
        return Err(file_error(path, "a configuration file must hold a table of settings".into()));
    }
    if value.get("train").is_some() && value.get("scene").is_some() {
        return Ok(SettingsFile { settings: value["train"].clone(), run: Some(value) });
    }
    Ok(SettingsFile { settings: value, run: None })
}

/// The first non-finite float of a TOML value, as (dotted key, value).
fn non_finite(v: &toml::Value, key: &str) -> Option<(String, f64)> {
    match v {
        toml::Value::Float(f) if !f.is_finite() => Some((key.to_string(), *f)),
        toml::Value::Table(t) => t.iter().find_map(|(k, x)| non_finite(x, &if key.is_empty() { k.clone() } else { format!("{key}.{k}") })),
        toml::Value::Array(a) => a.iter().enumerate().find_map(|(i, x)| non_finite(x, &format!("{key}[{i}]"))),
        _ => None,
    }
}

impl SettingsFile {
    /// The preset the file names (`preset = "fast"`), if any; an unknown name is an error.
    pub fn preset(&self, path: &Path) -> Result<Option<Preset>> {
        match self.settings.get("preset") {
            None => Ok(None),
            Some(Value::String(name)) => {
                name.parse().map(Some).map_err(|e: String| file_error(path, format!("the file's preset: {e}")))
            }
            Some(other) => Err(file_error(path, format!("the file's preset is {other}, not a preset name such as \"fast\""))),
        }
    }

    /// The configuration this file gives on its own: its preset (else `standard`) with the
    /// file's settings applied, validated. (`vagsl train` applies its flags in between.)
    pub fn config(&self, path: &Path) -> Result<TrainConfig> {
        let base = TrainConfig::preset(self.preset(path)?.unwrap_or_default());
        let config = base.with_overlay(&self.settings).map_err(|e| file_error(path, e.to_string()))?;
        config.validate()?;
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_and_json_files_and_run_configurations() {
        let toml = parse_settings_file(b"preset = \"fast\"\n[weights]\nlambda_f = 0.5\n", Path::new("a.toml")).unwrap();
        assert!(toml.run.is_none());
        let c = toml.config(Path::new("a.toml")).unwrap();
        assert_eq!(c.weights.lambda_f, 0.5);
        let json = serde_json::to_vec(&c).unwrap();
        assert_eq!(parse_settings_file(&json, Path::new("c.json")).unwrap().config(Path::new("c.json")).unwrap(), c);
        let run = parse_settings_file(br#"{"train": {"seed": 3}, "scene": {}}"#, Path::new("config.json")).unwrap();
        assert_eq!((run.settings["seed"].as_u64(), run.run.is_some()), (Some(3), true));
        for (bytes, name, says) in [
            (&b"seed = "[..], "b.toml", "not valid TOML"),
            (b"{\"seed\": ", "b.json", "not valid JSON"),
            (b"[1, 2]", "b.json", "table of settings"),
            (b"\xff\xfe", "b.json", "not UTF-8"),
            (b"[weights]\nlambda_p = nan\n", "n.toml", "weights.lambda_p = NaN: must be a finite number"),
            (b"background = [0, inf, 0]\n", "n.toml", "background[1] = inf: must be a finite number"),
            (b"{\"seed\": 1, \"near\": NaN}", "n.json", "'near' at line 1 column"),
        ] {
            let e = parse_settings_file(bytes, Path::new(name)).unwrap_err().to_string();
            assert!(e.starts_with(name) && e.contains(says), "{e}");
        }
        let bad = parse_settings_file(b"preset = \"slow\"", Path::new("p.toml")).unwrap();
        assert!(bad.config(Path::new("p.toml")).unwrap_err().to_string().contains("slow"));
    }
}
