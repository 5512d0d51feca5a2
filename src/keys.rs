//! Configuration keys that were renamed: files written with the old name
//! still load (serde aliases on the fields), and [`renamed_in`] lists the old
//! names a file uses so that the command line can say once what to write
//! instead.

/// `(old dotted key, new dotted key)` of the gyro model TOML.
pub const MODEL_RENAMES: &[(&str, &str)] = &[("gyro.pulse_weight_arcsec", "gyro.pulse_arcsec")];

/// `(old dotted key, new dotted key)` of the daemon configuration TOML.
pub const DAEMON_RENAMES: &[(&str, &str)] = &[("gyro.rate_hz", "gyro.sample_rate_hz")];

/// The dotted keys (`section.key`, and each `section`) of TOML text, with
/// renamed keys under their new names; empty when the text is not TOML.
pub fn dotted_keys(text: &str, renames: &[(&str, &str)]) -> std::collections::BTreeSet<String> {
    let mut keys = std::collections::BTreeSet::new();
    if let Ok(table) = text.parse::<toml::Table>() {
        for (section, value) in &table {
            keys.insert(section.clone());
            if let Some(t) = value.as_table() {
                keys.extend(t.keys().map(|k| {
                    let dotted = format!("{section}.{k}");
                    match renames.iter().find(|(old, _)| *old == dotted) {
                        Some((_, new)) => new.to_string(),
                        None => dotted,
                    }
                }));
            }
        }
    }
    keys
}

/// The old names `text` uses, with their new names.
pub fn renamed_in(
    text: &str,
    renames: &[(&'static str, &'static str)],
) -> Vec<(&'static str, &'static str)> {
    let Ok(table) = text.parse::<toml::Table>() else {
        return Vec::new();
    };
    renames
        .iter()
        .filter(|(old, _)| {
            let (section, key) = old.split_once('.').expect("a dotted key");
            table
                .get(section)
                .and_then(|v| v.as_table())
                .is_some_and(|t| t.contains_key(key))
        })
        .copied()
        .collect()
}

/// The warning for one renamed key in `origin`.
pub fn rename_warning(origin: &str, old: &str, new: &str) -> String {
    format!("{origin}: `{old}` is now `{new}`; the old name still loads, write the new one")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_names_are_found_and_counted_as_the_new() {
        let text = "[gyro]\nrate_hz = 1000.0\npulse_arcsec = 1.0\n[run]\nduration_s = 1\n";
        assert_eq!(
            renamed_in(text, DAEMON_RENAMES),
            vec![("gyro.rate_hz", "gyro.sample_rate_hz")]
        );
        let k = dotted_keys(text, DAEMON_RENAMES);
        assert!(k.contains("gyro.sample_rate_hz") && !k.contains("gyro.rate_hz"));
        assert!(k.contains("gyro.pulse_arcsec") && k.contains("run"));
        assert!(renamed_in("[gyro]\nsample_rate_hz = 1.0\n", DAEMON_RENAMES).is_empty());
        assert!(renamed_in("not toml [", MODEL_RENAMES).is_empty());
    }
}
