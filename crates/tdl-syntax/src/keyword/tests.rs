//! Unit tests for keyword words: joined forms, case, underscores and synonyms.

use syn::parse::{ParseStream, Parser};

use super::{peek_phrase, split, take_words};

#[test]
fn splits_joined_keywords() {
    assert_eq!(split("expandfirst"), Some(vec!["expand", "first"]));
    assert_eq!(split("disableuntil"), Some(vec!["disable", "until"]));
    assert_eq!(
        split("sequentialplanning"),
        Some(vec!["sequential", "expansion"])
    );
    assert_eq!(
        split("sequentialachievement"),
        Some(vec!["sequential", "execution"])
    );
    assert_eq!(split("maxactivations"), Some(vec!["maximum", "activate"]));
    assert_eq!(split("maxtriggers"), Some(vec!["maximum", "trigger"]));
    assert_eq!(split("onterminate"), Some(vec!["on", "terminate"]));
    assert_eq!(
        split("executioncompleted"),
        Some(vec!["execution", "completed"])
    );
    assert_eq!(
        split("terminateatexternal"),
        Some(vec!["terminate", "at", "external"])
    );
    assert_eq!(split("denyifbusy"), Some(vec!["deny", "if", "busy"]));
    assert_eq!(split("uses"), Some(vec!["uses"]));
    assert_eq!(split("monitorpickup"), None);
    assert_eq!(split("waiter"), None);
}

/// Whether `src` starts with `words` and, if so, what is left after taking them.
fn phrase(src: &str, words: &[&str]) -> Option<String> {
    let words = words.to_vec();
    (move |input: ParseStream| {
        if !peek_phrase(input, &words) {
            let _ = input.parse::<proc_macro2::TokenStream>();
            return Ok(None);
        }
        take_words(input, words.len())?;
        Ok(Some(input.parse::<proc_macro2::TokenStream>()?.to_string()))
    })
    .parse_str(src)
    .ok()
    .flatten()
}

#[test]
fn joined_underscored_and_cased_forms_match() {
    for src in [
        "expand first x",
        "expand_first x",
        "EXPAND__FIRST x",
        "expandfirst x",
        "Expand_First x",
    ] {
        assert_eq!(
            phrase(src, &["expand", "first"]).as_deref(),
            Some("x"),
            "{src}"
        );
    }
    for src in [
        "disable until x",
        "DISABLE_UNTIL x",
        "dIsAbLe___UnTiL x",
        "DiSaBlEuNtIl x",
    ] {
        assert_eq!(
            phrase(src, &["disable", "until"]).as_deref(),
            Some("x"),
            "{src}"
        );
    }
}

#[test]
fn synonyms_match_canonical_words() {
    assert!(phrase("delay planning", &["delay", "expansion"]).is_some());
    assert!(phrase("sequential_achievement", &["sequential", "execution"]).is_some());
    assert!(phrase("max activations", &["maximum", "activate"]).is_some());
}

#[test]
fn phrase_must_end_on_identifier_boundary() {
    // `terminate_at` holds two words; `terminate` alone cannot be taken from it.
    assert_eq!(phrase("terminate_at x", &["terminate"]), None);
    assert!(phrase("terminate_at x", &["terminate", "at"]).is_some());
    assert_eq!(phrase("expand second", &["expand", "first"]), None);
}
