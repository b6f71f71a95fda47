//! "Did you mean": the closest known names to a misspelt one, for the end of an error
//! message. The one rule for every name a user can mistype (a register, a parameter, a
//! device's attribute, through `benchbus._device.did_you_mean` too): up to three names
//! whose similarity to the given one, letter case aside, is at least 0.6, best first, as
//! Python's `difflib.get_close_matches` ranks them (the ratio `2 * M / T` of matched
//! characters, matched by longest common blocks).

/// How many names a hint offers at most.
const MOST: usize = 3;

/// The least similarity of a name offered.
const CUTOFF: f64 = 0.6;

/// `; did you mean 'a' or 'b'?` naming up to three of `known` closest to `name` (letter
/// case aside), or `""` when none is close: what a typo's error message ends with.
pub fn did_you_mean<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    let close = closest(name, known);
    if close.is_empty() {
        return String::new();
    }
    let quoted: Vec<String> = close.iter().map(|n| format!("'{n}'")).collect();
    format!("; did you mean {}?", quoted.join(" or "))
}

/// Up to three of `known` closest to `name`, letter case aside, best first (among equally
/// close ones, as `difflib.get_close_matches` orders them: the later name first).
pub fn closest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let wanted: Vec<char> = name.to_lowercase().chars().collect();
    // One name per folded spelling (the last in sorted order, as a dict built from the
    // sorted names keeps it).
    let mut names: Vec<&str> = known.into_iter().collect();
    names.sort_unstable();
    let mut folded: Vec<(String, &str)> = Vec::new();
    for n in names {
        let key = n.to_lowercase();
        match folded.iter_mut().find(|(k, _)| *k == key) {
            Some(slot) => slot.1 = n,
            None => folded.push((key, n)),
        }
    }
    let mut scored: Vec<(f64, &String, &str)> = folded
        .iter()
        .filter_map(|(key, n)| {
            let candidate: Vec<char> = key.chars().collect();
            let score = ratio(&candidate, &wanted);
            (score >= CUTOFF).then_some((score, key, *n))
        })
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0).then_with(|| b.1.cmp(a.1)));
    scored.into_iter().take(MOST).map(|(_, _, n)| n).collect()
}

/// `difflib.SequenceMatcher(None, a, b).ratio()`: twice the characters in matching blocks
/// over the length of both (1.0 for two empty names).
fn ratio(a: &[char], b: &[char]) -> f64 {
    let total = a.len() + b.len();
    if total == 0 {
        return 1.0;
    }
    2.0 * matched(a, b) as f64 / total as f64
}

/// The characters of `a` and `b` in matching blocks: the longest common block (the
/// earliest in `a`, then in `b`), then the same on each side of it.
fn matched(a: &[char], b: &[char]) -> usize {
    let (i, j, size) = longest_block(a, b);
    if size == 0 {
        return 0;
    }
    size + matched(&a[..i], &b[..j]) + matched(&a[i + size..], &b[j + size..])
}

/// The longest block common to `a` and `b`: where it starts in each, and its length.
fn longest_block(a: &[char], b: &[char]) -> (usize, usize, usize) {
    let mut best = (0, 0, 0);
    // ends[j + 1]: the length of the common block ending at a[i - 1] and b[j].
    let mut ends = vec![0usize; b.len() + 1];
    for (i, ca) in a.iter().enumerate() {
        let mut next = vec![0usize; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            if ca == cb {
                let k = ends[j] + 1;
                next[j + 1] = k;
                if k > best.2 {
                    best = (i + 1 - k, j + 1 - k, k);
                }
            }
        }
        ends = next;
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_typo_names_the_closest_names() {
        let known = ["speed", "speed_setpoint", "accel_time", "state"];
        assert_eq!(did_you_mean("sped", known), "; did you mean 'speed'?");
        assert_eq!(
            did_you_mean("Accel_Time", known),
            "; did you mean 'accel_time'?"
        );
        assert_eq!(did_you_mean("zzzz", known), "");
    }

    #[test]
    fn the_ratio_is_difflibs() {
        // difflib.SequenceMatcher(None, "abcd", "bcde").ratio() == 0.75
        let a: Vec<char> = "abcd".chars().collect();
        let b: Vec<char> = "bcde".chars().collect();
        assert!((ratio(&a, &b) - 0.75).abs() < 1e-12);
        // ("qabxcd", "abycdf"): blocks "ab" and "cd", 8 / 12
        let a: Vec<char> = "qabxcd".chars().collect();
        let b: Vec<char> = "abycdf".chars().collect();
        assert!((ratio(&a, &b) - 8.0 / 12.0).abs() < 1e-12);
    }

    #[test]
    fn at_most_three_best_first() {
        let known = ["pv1", "pv2", "pv3", "pv4", "sv"];
        assert_eq!(closest("pv", known), ["pv4", "pv3", "pv2"]);
    }
}
