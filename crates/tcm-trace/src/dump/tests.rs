//! Unit tests for `dump.rs`: both dump forms of a small tree.

use super::{dump_modern, dump_tcm};
use crate::event::TraceKind;
use crate::replay::Replay;
use crate::test_util::*;

fn replay_of(b: &Tb) -> Replay {
    let mut r = Replay::new();
    for ev in b.build() {
        assert_eq!(r.apply(&ev), Ok(()));
    }
    r
}

fn tree() -> Tb {
    let mut b = Tb::new();
    b.goal(1, 0, "deliver_mail").start_goal(1).tr(1, X, D, E);
    b.goal(2, 1, "navigate")
        .command(3, 1, "speak")
        .command(4, 1, "gone");
    b.tr(1, H, A, C);
    b.start_command(3).tr(1, X, E, A);
    b.start_command(4)
        .finish_command(4)
        .push(TraceKind::Reclaimed { node: 4 });
    b.push(TraceKind::Terminating { node: 3 })
        .push(TraceKind::Suspended { node: 2 });
    b
}

#[test]
fn tcm_form() {
    assert_eq!(
        dump_tcm(&replay_of(&tree())),
        "\
Root Node {0} [uh|ag|pg|al]
   deliver_mail {1} [hd|ag|pg|al]
      navigate {2} [uh|ua|up|al]
      speak {3} [hg|ag|pd|tg]
"
    );
    assert_eq!(dump_tcm(&Replay::new()), "Root Node {0} [uh|ag|pg|al]\n");
}

#[test]
fn modern_form() {
    assert_eq!(
        dump_modern(&replay_of(&tree())),
        "\
Root Node {0}  handling=active expansion=active execution=active
  deliver_mail {1}  handling=completed expansion=active execution=active
    navigate {2}  handling=disabled expansion=disabled execution=disabled suspended
    speak {3}  handling=active expansion=completed execution=active terminating
"
    );
}

#[test]
fn deep_tree_does_not_overflow_the_stack() {
    let mut b = Tb::new();
    for i in 1..=3_000u64 {
        b.goal(i, i - 1, "g");
    }
    let text = dump_tcm(&replay_of(&b));
    assert_eq!(text.lines().count(), 3_001);
}
