//! TOML's errors in the file's own terms: the key's path, the expected value in words,
//! the line and column.

use crate::*;

/// A number for a message: plain where that reads well, else in exponent form, so that
/// 1e-300 is not printed with three hundred zeros.
pub(crate) fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// The 1-based line and column of byte `offset` in `text`.
pub(crate) fn position_of(text: &str, offset: usize) -> TextPosition {
    let offset = offset.min(text.len());
    // A span may in principle end inside a multi-byte character; step back to a boundary
    // so slicing never panics.
    let mut offset = offset;
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let col = before[line_start..].chars().count() + 1;
    TextPosition {
        line: u32::try_from(line).unwrap_or(u32::MAX),
        col: u32::try_from(col).unwrap_or(u32::MAX),
    }
}

// serde's messages in the file's terms. The raw layout below is read by serde, whose
// messages speak Rust (`invalid type: floating point `1.5`, expected i64`, `missing field
// `z``). Every such message is translated here, for every key alike: the key is found from
// the error's place in the text, the expected value is said in words with the unit its key
// name carries, and the value found is quoted as written in the file.

/// `error`'s message in the file's terms.
pub(crate) fn in_file_terms(text: &str, error: &toml::de::Error) -> String {
    let message = error.message().trim_end();
    let Some(span) = error.span() else {
        return message.to_string();
    };
    let written = text
        .get(span.clone())
        .and_then(|v| v.lines().next())
        .map(|v| v.trim())
        .unwrap_or("");
    let written = if written.chars().count() > 40 {
        format!("{}...", written.chars().take(40).collect::<String>())
    } else {
        written.to_string()
    };
    if let Some(field) = between(message, "missing field `", "`") {
        // The span is the table the key is missing from.
        let key = join(&table_path_of(text, &span), field);
        return if TABLES.contains(&generic(&key).as_str()) {
            format!("missing table [{key}]")
        } else {
            format!("missing key `{key}`")
        };
    }
    if let Some(field) = between(message, "unknown field `", "`") {
        let key = key_path_at(text, span.start).unwrap_or_else(|| field.to_string());
        let expected = message
            .split_once(", expected ")
            .map(|(_, keys)| format!(" (known here: {})", keys.trim_start_matches("one of ")))
            .unwrap_or_default();
        return format!("unknown key `{key}`{expected}");
    }
    let expected = message
        .strip_prefix("invalid type: ")
        .or_else(|| message.strip_prefix("invalid value: "))
        .and_then(|m| m.split_once(", expected "))
        .map(|(_, expected)| expected);
    match (expected, key_path_at(text, span.start)) {
        (Some(expected), Some(key)) => {
            format!(
                "`{key}` must be {}, found {written}",
                expected_in_words(expected, &key)
            )
        }
        (None, Some(key)) => format!("`{key}`: {message}"),
        (_, None) => message.to_string(),
    }
}

/// The keys whose values are tables, with `*` for the rotary or linear axis name.
pub(crate) const TABLES: [&str; 9] = [
    "axes",
    "axes.x",
    "axes.y",
    "axes.z",
    "axes.*.drive",
    "daemon",
    "gcode",
    "work_offsets",
    "safety",
];

/// `key` with an axis table's name replaced by `*` when it is below it (`axes.x.drive`
/// becomes `axes.*.drive`).
pub(crate) fn generic(key: &str) -> String {
    let parts: Vec<&str> = key.split('.').collect();
    if parts.len() > 2 && parts[0] == "axes" {
        let mut parts = parts;
        parts[1] = "*";
        return parts.join(".");
    }
    key.to_string()
}

pub(crate) fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

/// The text between `start` and the next `end` after it, when `text` starts with `start`.
pub(crate) fn between<'t>(text: &'t str, start: &str, end: &str) -> Option<&'t str> {
    let rest = text.strip_prefix(start)?;
    rest.split_once(end).map(|(inside, _)| inside)
}

/// serde's expectation (`i64`, `f64`, `a string`, `a boolean`, `a sequence`, ...) in words,
/// with the unit the key's name ends with.
pub(crate) fn expected_in_words(expected: &str, key: &str) -> String {
    let last = key.rsplit('.').next().unwrap_or(key);
    let unit = unit_of(last);
    let integer = matches!(
        expected,
        "i8" | "i16" | "i32" | "i64" | "i128" | "u8" | "u16" | "u32" | "u64" | "u128" | "usize"
    ) || expected.contains("integer");
    if integer {
        return match unit {
            Some(unit) => format!("a whole number of {unit}"),
            None => "a whole number".to_string(),
        };
    }
    if matches!(expected, "f32" | "f64") || expected.contains("float") {
        return match unit {
            Some(unit) => format!("a number in {unit}"),
            None => "a number".to_string(),
        };
    }
    if expected.contains("string") {
        return "a string in double quotes".to_string();
    }
    if expected.contains("bool") {
        return "true or false".to_string();
    }
    if expected.contains("sequence") {
        return match unit {
            Some(unit) => format!("an array of numbers in {unit}, such as [0.0, 0.0, 0.0]"),
            None => "an array in brackets, such as [\"a\", \"b\"]".to_string(),
        };
    }
    if expected.contains("struct") || expected.contains("map") {
        return format!("a table ([{key}])");
    }
    expected.to_string()
}

/// The unit a key name ends with, in words (`period_us`: microseconds).
pub(crate) fn unit_of(key: &str) -> Option<&'static str> {
    const UNITS: [(&str, &str); 21] = [
        ("_mm_s3", "mm/s³"),
        ("_mm_s2", "mm/s²"),
        ("_mm_s", "mm/s"),
        ("_deg_s3", "degrees/s³"),
        ("_deg_s2", "degrees/s²"),
        ("_deg_s", "degrees/s"),
        ("_counts_s2", "counts/s²"),
        ("_mm_deg", "mm (degrees for A, B, C)"),
        ("_counts", "counts"),
        ("_cycles", "cycles"),
        ("_seconds", "seconds"),
        ("_us", "microseconds"),
        ("_ns", "nanoseconds"),
        ("_ms", "milliseconds"),
        ("_hz", "Hz"),
        ("_mm", "mm"),
        ("_deg", "degrees"),
        ("_rpm_s", "rpm/s"),
        ("_rpm", "rpm"),
        ("_s", "seconds"),
        ("_pct", "percent"),
    ];
    UNITS
        .iter()
        .find(|(suffix, _)| key.ends_with(suffix))
        .map(|(_, unit)| *unit)
}

/// The dotted key (`axes.x.velocity_mm_s`, `tools[1].number`) whose key or value holds the
/// byte at `at`, the one with the shortest such span; `None` when the text does not parse.
///
/// A table opened by a header (`[axes.x]`) has the header as its span, not its keys, so
/// every key of the file is looked at, not only those inside a span that holds `at`.
pub(crate) fn key_path_at(text: &str, at: usize) -> Option<String> {
    fn visit(
        value: &toml::de::DeValue<'_>,
        path: &str,
        at: usize,
        best: &mut Option<(usize, String)>,
    ) {
        fn consider(
            span: std::ops::Range<usize>,
            path: &str,
            at: usize,
            best: &mut Option<(usize, String)>,
        ) {
            if span.contains(&at) && best.as_ref().is_none_or(|(len, _)| span.len() < *len) {
                *best = Some((span.len(), path.to_string()));
            }
        }
        match value {
            toml::de::DeValue::Table(table) => {
                for (key, value) in table.iter() {
                    let here = join(path, key.get_ref());
                    consider(key.span(), &here, at, best);
                    consider(value.span(), &here, at, best);
                    visit(value.get_ref(), &here, at, best);
                }
            }
            toml::de::DeValue::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    let here = format!("{path}[{i}]");
                    consider(item.span(), &here, at, best);
                    visit(item.get_ref(), &here, at, best);
                }
            }
            _ => {}
        }
    }
    let root = toml::de::DeTable::parse(text).ok()?;
    let mut best = None;
    visit(
        &toml::de::DeValue::Table(root.into_inner()),
        "",
        at,
        &mut best,
    );
    best.map(|(_, path)| path)
}

/// The dotted name of the table whose span is `span` (the top level: empty).
pub(crate) fn table_path_of(text: &str, span: &std::ops::Range<usize>) -> String {
    fn find(
        value: &toml::de::DeValue<'_>,
        span: &std::ops::Range<usize>,
        path: &str,
    ) -> Option<String> {
        match value {
            toml::de::DeValue::Table(table) => table.iter().find_map(|(key, value)| {
                let here = join(path, key.get_ref());
                if value.span() == *span && matches!(value.get_ref(), toml::de::DeValue::Table(_)) {
                    return Some(here);
                }
                find(value.get_ref(), span, &here)
            }),
            toml::de::DeValue::Array(items) => items.iter().enumerate().find_map(|(i, item)| {
                let here = format!("{path}[{i}]");
                if item.span() == *span {
                    return Some(here);
                }
                find(item.get_ref(), span, &here)
            }),
            _ => None,
        }
    }
    toml::de::DeTable::parse(text)
        .ok()
        .and_then(|root| find(&toml::de::DeValue::Table(root.into_inner()), span, ""))
        .unwrap_or_default()
}

// The raw file layout. Values that are range-checked are `Spanned` so that the error can
// point at the value, not only name the key.
