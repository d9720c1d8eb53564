//! Configuration text for tests: the bundled example machine without its homing.

/// `text` (a machine configuration in TOML) without `[homing]` and without every axis's
/// `[axes.*.homing]`, `[axes.*.limit_switches]` and `[axes.*.sim]` tables: every axis
/// counts as homed at start with the drive's coordinates from power-up at 0, as before
/// homing existed, and no input is a home or limit switch. For the tests whose subject is
/// neither homing nor limit switches but that run programs on the bundled example machine
/// (which homes on simulated switches and refuses programs until it is homed).
pub fn without_homing(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut skipping = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            let name = t
                .trim_start_matches('[')
                .split(']')
                .next()
                .unwrap_or("")
                .trim();
            skipping = name == "homing"
                || (name.starts_with("axes.")
                    && (name.ends_with(".homing")
                        || name.ends_with(".sim")
                        || name.ends_with(".limit_switches")));
        }
        if !skipping {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_the_homing_tables_and_keeps_the_rest() {
        let text = "machine = \"m\"\n[axes.x]\nvelocity_mm_s = 1\n[axes.x.homing]\nkind = \"switch\"\n[axes.x.limit_switches]\nmin = \"a\"\n[axes.x.sim]\nstart_mm = 3\n[homing]\nrequired = true\n[jog]\ndeadman_ms = 100\n";
        assert_eq!(
            without_homing(text),
            "machine = \"m\"\n[axes.x]\nvelocity_mm_s = 1\n[jog]\ndeadman_ms = 100\n"
        );
    }
}
