//! Path patterns of breakpoints, faults and approvals (`Matcher::Path`): names from the
//! top-level task down joined by `/`; a `*` segment matches one name, `**` any number of names,
//! `*` inside a name any part of it.

/// Whether `path` (names joined by `/`) matches `pattern` (see `Matcher::Path`).
pub(crate) fn path_matches(pattern: &str, path: &str) -> bool {
    let pat: Vec<&str> = pattern.split('/').filter(|s| !s.is_empty()).collect();
    let names: Vec<&str> = path.split('/').collect();
    segments_match(&pat, &names)
}

fn segments_match(pat: &[&str], names: &[&str]) -> bool {
    match pat.split_first() {
        None => names.is_empty(),
        Some((&"**", rest)) => (0..=names.len()).any(|i| segments_match(rest, &names[i..])),
        Some((p, rest)) => names
            .split_first()
            .is_some_and(|(n, tail)| name_matches(p, n) && segments_match(rest, tail)),
    }
}

fn name_matches(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((head, tail)) => {
            name.len() >= head.len() + tail.len() && name.starts_with(head) && {
                let rest = &name[head.len()..];
                (0..=rest.len())
                    .filter(|i| rest.is_char_boundary(*i))
                    .any(|i| name_matches(tail, &rest[i..]))
                    || tail.is_empty()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::path_matches;

    #[test]
    fn paths_match_by_segment() {
        assert!(path_matches("a/b/c", "a/b/c"));
        assert!(!path_matches("a/b", "a/b/c"));
        assert!(path_matches("a/*/c", "a/b/c"));
        assert!(!path_matches("a/*/c", "a/b/d/c"));
        assert!(path_matches("a/**/c", "a/b/d/c"));
        assert!(path_matches("a/**/c", "a/c"));
        assert!(path_matches("**/guarded*", "deliver/navigate/guardedMove"));
        assert!(!path_matches("**/guarded*", "deliver/navigate/move"));
        assert!(path_matches("*Door", "centerOnDoor"));
        assert!(path_matches("c*n*r", "corner"));
        assert!(!path_matches("c*n*r", "corners"));
    }
}
