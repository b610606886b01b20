//! [`ShowArg`]: the argument types a node's `spawned` record shows (docs/trace-format.md), as
//! `Debug` prints them. Only types whose text is the same on every run are shown: no hash map
//! (its order differs between processes), no shared state whose contents change; a task's
//! argument of another type shows as `…`. A program shows its own types by implementing it.

use std::time::Duration;

/// The most items of a list a `spawned` record shows; the rest are `…`.
pub const SHOWN_ITEMS: usize = 8;

/// An argument type a node's `spawned` record shows (`name = value`): its text, the same on every
/// run for the same value.
pub trait ShowArg {
    /// Appends the value's text to `out`.
    fn show_arg(&self, out: &mut String);
}

macro_rules! shown_as_debug {
    ($($t:ty),*) => {$(
        impl ShowArg for $t {
            fn show_arg(&self, out: &mut String) {
                use std::fmt::Write as _;
                let _ = write!(out, "{self:?}");
            }
        }
    )*};
}

shown_as_debug!(
    (),
    bool,
    char,
    i8,
    i16,
    i32,
    i64,
    i128,
    isize,
    u8,
    u16,
    u32,
    u64,
    u128,
    usize,
    f64,
    str,
    String,
    Duration
);

/// As the `f64` it widens to, as TDL's interpreter holds it (so both print the same text).
impl ShowArg for f32 {
    fn show_arg(&self, out: &mut String) {
        f64::from(*self).show_arg(out);
    }
}

impl<T: ShowArg, const N: usize> ShowArg for [T; N] {
    fn show_arg(&self, out: &mut String) {
        show_items(self.iter(), N, out);
    }
}

impl<T: ShowArg + ?Sized> ShowArg for &T {
    fn show_arg(&self, out: &mut String) {
        (**self).show_arg(out);
    }
}

impl<T: ShowArg> ShowArg for Option<T> {
    fn show_arg(&self, out: &mut String) {
        match self {
            Some(v) => {
                out.push_str("Some(");
                v.show_arg(out);
                out.push(')');
            }
            None => out.push_str("None"),
        }
    }
}

impl<T: ShowArg> ShowArg for Vec<T> {
    fn show_arg(&self, out: &mut String) {
        show_items(self.iter(), self.len(), out);
    }
}

impl<T: ShowArg> ShowArg for [T] {
    fn show_arg(&self, out: &mut String) {
        show_items(self.iter(), self.len(), out);
    }
}

/// `[a, b, …]`: at most [`SHOWN_ITEMS`] items.
fn show_items<'a, T: ShowArg + 'a>(
    items: impl Iterator<Item = &'a T>,
    len: usize,
    out: &mut String,
) {
    out.push('[');
    for (i, it) in items.take(SHOWN_ITEMS).enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        it.show_arg(out);
    }
    if len > SHOWN_ITEMS {
        out.push_str(", …");
    }
    out.push(']');
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shown(v: &impl ShowArg) -> String {
        let mut out = String::new();
        v.show_arg(&mut out);
        out
    }

    #[test]
    fn values_show_as_debug_prints_them_and_long_lists_are_cut() {
        assert_eq!(shown(&"lab"), "\"lab\"");
        assert_eq!(shown(&String::from("a\"b")), "\"a\\\"b\"");
        assert_eq!(shown(&2.0_f64), "2.0");
        assert_eq!(shown(&Some(3_u8)), "Some(3)");
        assert_eq!(shown(&Duration::from_millis(1500)), "1.5s");
        assert_eq!(shown(&vec![1, 2]), "[1, 2]");
        let long: Vec<u32> = (0..20).collect();
        assert_eq!(shown(&long), "[0, 1, 2, 3, 4, 5, 6, 7, …]");
    }
}
