//! Unit tests for the resource rules of the checker: hand-made traces that use resources well
//! pass, and one that over-grants, one that leaks a grant, and each other misuse are caught.

use crate::check::{Rule, check, check_prefix};
use crate::event::{ResourceUse, TraceKind};
use crate::test_util::*;

fn arm(n: u32) -> Vec<ResourceUse> {
    vec![ResourceUse::new("arm", n)]
}

impl Tb {
    fn declare(&mut self, name: &str, capacity: u32, pending_limit: Option<u32>) -> &mut Tb {
        self.push(TraceKind::Resource {
            resource: name.into(),
            capacity,
            pending_limit,
        })
    }

    fn request(&mut self, node: u64, uses: Vec<ResourceUse>) -> &mut Tb {
        self.push(TraceKind::Requested {
            node,
            uses,
            priority: 0,
        })
    }

    fn grant(&mut self, node: u64, uses: Vec<ResourceUse>) -> &mut Tb {
        self.push(TraceKind::Granted { node, uses })
    }

    fn release(&mut self, node: u64, uses: Vec<ResourceUse>) -> &mut Tb {
        self.push(TraceKind::Released { node, uses })
    }

    /// Command `name` {node} under the root: execution and handling enabled, then it asks for
    /// `uses`.
    fn asks(&mut self, node: u64, name: &str, uses: Vec<ResourceUse>) -> &mut Tb {
        self.command(node, 0, name);
        self.tr(node, X, D, E).tr(node, H, D, E);
        self.request(node, uses)
    }

    /// The command {node}, granted, goes active.
    fn runs(&mut self, node: u64) -> &mut Tb {
        self.tr(node, H, E, A).tr(node, X, E, A)
    }

    /// The running command {node} gives back `uses` and completes.
    fn ends(&mut self, node: u64, uses: Vec<ResourceUse>) -> &mut Tb {
        self.release(node, uses).finish_command(node)
    }
}

/// `arm` of capacity 2; commands a {1} and b {2} hold one each, c {3} waits until a gives its
/// arm back.
fn three_users() -> Tb {
    let mut b = Tb::new();
    b.declare("arm", 2, None);
    b.asks(1, "a", arm(1)).grant(1, arm(1)).runs(1);
    b.asks(2, "b", arm(1)).grant(2, arm(1)).runs(2);
    b.asks(3, "c", arm(1));
    b
}

#[test]
fn a_third_user_waits_for_a_release() {
    let mut b = three_users();
    b.at(S).ends(1, arm(1)).grant(3, arm(1)).runs(3);
    b.at(2 * S).ends(2, arm(1)).ends(3, arm(1));
    match check(&b.build()) {
        Ok(r) => assert!(r.n_transitions > 0),
        Err(vs) => panic!("{vs:?}"),
    }
}

#[test]
fn an_over_grant_is_caught() {
    // c is granted the arm while a and b still hold both units.
    let mut b = three_users();
    b.grant(3, arm(1)).runs(3);
    caught(&b.build(), Rule::ResourceCapacity);
}

#[test]
fn a_leaked_grant_is_caught_when_the_handling_completes() {
    // a completes without giving its arm back.
    let mut b = three_users();
    b.at(S).finish_command(1);
    caught(&b.build(), Rule::ResourceRelease);
}

#[test]
fn a_terminated_node_releases_once_its_action_stopped() {
    let mut b = Tb::new();
    b.declare("arm", 1, None);
    b.asks(1, "a", arm(1)).grant(1, arm(1)).runs(1);
    b.at(S).push(TraceKind::Terminating { node: 1 });
    b.tr(1, H, A, C);
    let mut leaked = b.clone_for_test();
    // Its action stopped a moment later: the arm is given back before it is terminated.
    b.at(2 * S).release(1, arm(1)).tr(1, X, A, C);
    b.push(TraceKind::Terminated { node: 1 });
    assert_eq!(rules(&b.build()), Vec::<Rule>::new());
    leaked.at(2 * S).tr(1, X, A, C);
    leaked.push(TraceKind::Terminated { node: 1 });
    caught(&leaked.build(), Rule::ResourceRelease);
}

#[test]
fn going_active_without_the_grant_is_caught() {
    let mut b = three_users();
    b.runs(3);
    caught(&b.build(), Rule::ResourceGrant);
}

#[test]
fn a_waiting_request_left_behind_is_caught() {
    // c's request is neither granted nor withdrawn when its node is terminated.
    let mut b = three_users();
    b.push(TraceKind::Terminating { node: 3 });
    b.tr(3, H, E, C).tr(3, X, E, C);
    b.push(TraceKind::Terminated { node: 3 });
    caught(&b.build(), Rule::ResourceRelease);
    let mut ok = three_users();
    ok.push(TraceKind::Terminating { node: 3 });
    ok.push(TraceKind::Withdrawn { node: 3 });
    ok.tr(3, H, E, C).tr(3, X, E, C);
    ok.push(TraceKind::Terminated { node: 3 });
    assert_eq!(rules(&ok.build()), Vec::<Rule>::new());
}

#[test]
fn grants_of_locked_or_reserved_resources_are_caught() {
    let mut locked = Tb::new();
    locked.declare("arm", 1, None);
    locked.push(TraceKind::ResourceLocked {
        resource: "arm".into(),
    });
    locked.asks(1, "a", arm(1)).grant(1, arm(1));
    caught(&locked.build(), Rule::ResourceLock);

    let mut reserved = Tb::new();
    reserved.declare("arm", 1, None);
    reserved.goal(1, 0, "owner").start_goal(1);
    reserved.push(TraceKind::ResourceReserved {
        resource: "arm".into(),
        holder: 1,
    });
    let mut inside = reserved.clone_for_test();
    reserved.asks(2, "stranger", arm(1)).grant(2, arm(1));
    caught(&reserved.build(), Rule::ResourceLock);
    // A child of the holder may have it.
    inside.command(2, 1, "own");
    inside.tr(1, X, D, E).tr(2, X, D, E).tr(2, H, D, E);
    inside.request(2, arm(1)).grant(2, arm(1));
    assert_eq!(rules(&inside.build()), Vec::<Rule>::new());
}

#[test]
fn more_requests_waiting_than_the_pending_limit_are_caught() {
    let mut b = Tb::new();
    b.declare("arm", 1, Some(1));
    b.asks(1, "a", arm(1)).grant(1, arm(1)).runs(1);
    b.asks(2, "b", arm(1));
    let mut ok = b.clone_for_test();
    b.asks(3, "c", arm(1));
    b.asks(4, "d", arm(1));
    caught(&b.build(), Rule::ResourcePending);
    // The oldest waiting request is dropped when c comes.
    ok.asks(3, "c", arm(1));
    ok.push(TraceKind::Dropped {
        node: 2,
        resource: "arm".into(),
    });
    ok.push(TraceKind::Failed {
        node: 2,
        exception: "ResourceDropped".into(),
        message: "dropped".into(),
    });
    ok.tr(2, H, E, C).tr(2, X, E, C);
    assert_eq!(rules(&ok.build()), Vec::<Rule>::new());
}

#[test]
fn records_that_do_not_fit_are_caught() {
    // An undeclared resource; a release without a grant; a grant of other amounts.
    let mut b = Tb::new();
    b.command(1, 0, "a");
    b.tr(1, X, D, E).tr(1, H, D, E);
    b.request(1, vec![ResourceUse::new("gripper", 1)]);
    caught(&b.build(), Rule::ResourceRequest);

    let mut b = Tb::new();
    b.declare("arm", 2, None);
    b.asks(1, "a", arm(1)).release(1, arm(1));
    caught(&b.build(), Rule::ResourceRequest);

    let mut b = Tb::new();
    b.declare("arm", 2, None);
    b.asks(1, "a", arm(1)).grant(1, arm(2));
    caught(&b.build(), Rule::ResourceRequest);

    let mut b = Tb::new();
    b.declare("arm", 2, None).declare("arm", 1, None);
    caught(&b.build(), Rule::ResourceRequest);
}

#[test]
fn a_prefix_may_end_while_grants_are_held() {
    let b = three_users();
    assert!(check_prefix(&b.build()).is_ok());
    assert!(check(&b.build()).is_ok());
}
