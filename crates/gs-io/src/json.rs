//! JSON errors in words: JSON has no NaN or Infinity, and serde_json reports one only as
//! "expected value at line L column C"; the key it stands under is named instead.

/// The words for a JSON parse error `e` of `text`: for a `NaN`, `Infinity` or `-Infinity`
/// literal, the key it stands under and that the value must be a finite number; otherwise
/// serde_json's own message.
pub fn json_error_words(text: &[u8], e: &serde_json::Error) -> String {
    match non_finite_at(text, e.line(), e.column()) {
        Some((key, literal)) => format!(
            "'{key}' at line {} column {} is {literal}: it must be a finite number (JSON has no NaN or Infinity)",
            e.line(),
            e.column()
        ),
        None => format!("malformed JSON: {e}"),
    }
}

/// The key and literal of a non-finite number at 1-based `line`, `column` of `text`.
fn non_finite_at(text: &[u8], line: usize, column: usize) -> Option<(String, &'static str)> {
    let start = text.split(|&b| b == b'\n').take(line.saturating_sub(1)).map(|l| l.len() + 1).sum::<usize>();
    let at = (start + column.saturating_sub(1)).min(text.len());
    // serde_json points at or just after the literal's first byte.
    let from = at.saturating_sub(2).max(start);
    let rest = &text[from..];
    let literal = ["-Infinity", "Infinity", "NaN", "-inf", "inf", "nan", "-nan"]
        .into_iter()
        .find_map(|l| rest.windows(l.len()).take(3).any(|w| w.eq_ignore_ascii_case(l.as_bytes())).then_some(l))?;
    let before = &text[..at];
    let colon = before.iter().rposition(|&b| b == b':')?;
    let close = before[..colon].iter().rposition(|&b| b == b'"')?;
    let open = before[..close].iter().rposition(|&b| b == b'"')?;
    Some((String::from_utf8_lossy(&before[open + 1..close]).into_owned(), literal))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(text: &str) -> String {
        let e = serde_json::from_str::<serde_json::Value>(text).unwrap_err();
        json_error_words(text.as_bytes(), &e)
    }

    #[test]
    fn a_nan_names_its_key() {
        let w = words("{\n  \"camera_angle_x\": 0.7,\n  \"fl_x\": NaN,\n  \"w\": 800\n}");
        assert!(w.starts_with("'fl_x' at line 3") && w.contains("is NaN") && w.contains("finite number"), "{w}");
        let w = words("{\"frames\": [{\"transform_matrix\": [[1, 0, 0, -Infinity]]}]}");
        assert!(w.starts_with("'transform_matrix'") && w.contains("-Infinity"), "{w}");
        let w = words("{\"a\": 1,, }");
        assert!(w.starts_with("malformed JSON:"), "{w}");
    }
}
