//! ROS 2 actions and services as the `extern` tasks of TDL programs run by the interpreter
//! (`tdl_interp`; docs/language.md, "Running programs without compiling them"): registered in a
//! [`Registry`] under a name, a program that declares `extern command fib(order: i64) -> Json;`
//! and spawns `fib(5)` sends a goal of the action (or a request of the service) and waits for its
//! result as for any task.
//!
//! - Arguments: by default ([`action`], [`service`]) the goal or request is read by serde from a
//!   JSON object keyed by the parameter names given at registration (the extern's, in order),
//!   each argument converted with `Value::to_json`: `fib(5)` with the names `["order"]` reads
//!   `{"order": 5}`. With no names, the one argument the program passes (a map it built) is the
//!   whole message, and no argument is the empty object (a message without fields). An argument
//!   that has no JSON form, the wrong number of arguments, or JSON that does not make the
//!   message fails the spawning node with `TypeMismatch`, as an argument of the wrong type does
//!   for the interpreter. [`action_with`] and [`service_with`] take a closure over the values
//!   instead.
//! - Value: the result (or response) becomes a plain value of the program, through JSON
//!   (`Value::from_json`): a message is a map whose fields the program reads (`r.sequence`).
//! - Failures: the goal's task fails as it does in a Rust tree ([`ActionAborted`],
//!   [`ActionCanceled`], [`GoalRejected`], [`RosTimeout`], their ancestor [`RosError`]), and the
//!   registration declares these exceptions to the registry, so a program writes `handles
//!   ActionAborted as e` without declaring them. The exception's data becomes a record of its
//!   fields, which the program reads (`e.downcast::<ActionAborted>()` gives `action`, `goal`,
//!   `result`); Rust code that looks at the failure gets that record, not the Rust type.
//! - Termination: terminating the node cancels the goal on the server, as [`ActionClient::goal`]
//!   does (a service's request is dropped).

use std::sync::Arc;

use serde::Serialize;
use serde::de::DeserializeOwned;
use tcm::{Exception, Failure};
use tdl_interp::{Record, Registry, Value};

use crate::client::{ActionClient, ServiceClient};
use crate::failure::{ActionAborted, ActionCanceled, GoalRejected, RosError, RosTimeout};

/// Declares this crate's exceptions ([`RosError`] and its descendants) to `registry`, with their
/// ancestors, so that a program handles them by name without declaring them. The registrations
/// below do it themselves.
pub fn exceptions(registry: &mut Registry) -> &mut Registry {
    registry
        .exception(RosError::name(), RosError::ancestry())
        .exception(ActionAborted::name(), ActionAborted::ancestry())
        .exception(ActionCanceled::name(), ActionCanceled::ancestry())
        .exception(GoalRejected::name(), GoalRejected::ancestry())
        .exception(RosTimeout::name(), RosTimeout::ancestry())
}

/// Registers the action of `client` as the task `name`, its goal read from the arguments named
/// `params` (the extern's parameter names, in order; see the module's documentation). The node
/// is named `name`.
pub fn action<'r, G, R, F>(
    registry: &'r mut Registry,
    name: &str,
    client: &ActionClient<G, R, F>,
    params: &[&str],
) -> &'r mut Registry
where
    G: Serialize + DeserializeOwned + Clone + Send + Sync + 'static,
    R: DeserializeOwned + Serialize + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    let what = format!("the goal of `{name}` ({})", client.action());
    let params: Vec<String> = params.iter().map(|p| (*p).to_string()).collect();
    action_with(registry, name, client, move |args| {
        message_of(&what, &params, args)
    })
}

/// Registers the action of `client` as the task `name`, its goal built by `goal` from the
/// arguments (a failure it returns fails the spawning node).
pub fn action_with<'r, G, R, F>(
    registry: &'r mut Registry,
    name: &str,
    client: &ActionClient<G, R, F>,
    goal: impl Fn(&[Value]) -> Result<G, Failure> + Send + Sync + 'static,
) -> &'r mut Registry
where
    G: Serialize + Clone + Send + Sync + 'static,
    R: DeserializeOwned + Serialize + Send + 'static,
    F: DeserializeOwned + Send + 'static,
{
    let client = client.clone();
    let node = name.to_string();
    exceptions(registry).task_dynamic(name, move |args| {
        let goal = goal(args)?;
        Ok(client.goal(goal).named(node.clone()).task_then(for_program))
    })
}

/// Registers the service of `client` as the task `name`, its request read from the arguments
/// named `params` (as for [`action`]). The node is named `name`.
pub fn service<'r, Q, A>(
    registry: &'r mut Registry,
    name: &str,
    client: &ServiceClient<Q, A>,
    params: &[&str],
) -> &'r mut Registry
where
    Q: Serialize + DeserializeOwned + Clone + Send + Sync + 'static,
    A: DeserializeOwned + Serialize + Send + 'static,
{
    let what = format!("the request of `{name}` ({})", client.service());
    let params: Vec<String> = params.iter().map(|p| (*p).to_string()).collect();
    service_with(registry, name, client, move |args| {
        message_of(&what, &params, args)
    })
}

/// Registers the service of `client` as the task `name`, its request built by `request` from the
/// arguments.
pub fn service_with<'r, Q, A>(
    registry: &'r mut Registry,
    name: &str,
    client: &ServiceClient<Q, A>,
    request: impl Fn(&[Value]) -> Result<Q, Failure> + Send + Sync + 'static,
) -> &'r mut Registry
where
    Q: Serialize + Clone + Send + Sync + 'static,
    A: DeserializeOwned + Serialize + Send + 'static,
{
    let client = client.clone();
    let node = name.to_string();
    exceptions(registry).task_dynamic(name, move |args| {
        let request = request(args)?;
        Ok(client
            .call(request)
            .named(node.clone())
            .task_then(for_program))
    })
}

/// A message read from a program's arguments as [`action`] reads a goal: the object keyed by
/// `params` (one argument each), or with no names the one argument itself (no argument: `{}`).
/// Fails with `TypeMismatch`; `what` names the message in the failure's text. For closures given
/// to [`action_with`] and [`service_with`] that read part of the message this way.
pub fn message_of<T: DeserializeOwned, S: AsRef<str>>(
    what: &str,
    params: &[S],
    args: &[Value],
) -> Result<T, Failure> {
    let mismatch = |why: String| Failure::new("TypeMismatch", format!("{what}: {why}"));
    let mut json = Vec::with_capacity(args.len());
    for (i, a) in args.iter().enumerate() {
        json.push(
            a.to_json()
                .map_err(|e| mismatch(format!("argument {}: {e}", i + 1)))?,
        );
    }
    let object = if params.is_empty() {
        match json.len() {
            0 => serde_json::Value::Object(serde_json::Map::new()),
            1 => json.pop().unwrap_or_default(),
            n => {
                return Err(mismatch(format!(
                    "{n} arguments and no parameter names: name them at registration, or pass \
                     one map"
                )));
            }
        }
    } else if params.len() == json.len() {
        serde_json::Value::Object(
            params
                .iter()
                .map(|p| p.as_ref().to_string())
                .zip(json)
                .collect(),
        )
    } else {
        let names: Vec<&str> = params.iter().map(AsRef::as_ref).collect();
        return Err(mismatch(format!(
            "{} argument(s) for the parameters {names:?}",
            json.len()
        )));
    };
    serde_json::from_value(object.clone()).map_err(|e| mismatch(format!("{e} (from {object})")))
}

/// A goal's or request's end as the interpreted program sees it: the result as a plain value,
/// a failure of this crate with its data as a record of its fields.
fn for_program<R: Serialize>(ended: Result<R, Failure>) -> Result<Value, Failure> {
    match ended {
        Ok(r) => serde_json::to_value(&r)
            .map(|j| Value::from_json(&j))
            .map_err(|e| RosError::failure(format!("the result has no JSON form: {e}"))),
        Err(f) => Err(with_record(f)),
    }
}

/// `f` with its data, if it is one of this crate's exceptions, replaced by a record of its fields
/// (what the interpreter reads with `.data()` and `.downcast::<E>()`).
fn with_record(mut f: Failure) -> Failure {
    fn json<E: Serialize + Send + Sync + 'static>(f: &Failure) -> Option<serde_json::Value> {
        f.data::<E>().and_then(|e| serde_json::to_value(&*e).ok())
    }
    let fields = json::<ActionAborted>(&f)
        .or_else(|| json::<ActionCanceled>(&f))
        .or_else(|| json::<GoalRejected>(&f))
        .or_else(|| json::<RosTimeout>(&f))
        .or_else(|| json::<RosError>(&f));
    if let Some(serde_json::Value::Object(fields)) = fields {
        let record = Value::Record(Arc::new(Record {
            name: Arc::from(&*f.exception),
            fields: fields
                .iter()
                .map(|(k, v)| (Arc::from(k.as_str()), Value::from_json(v)))
                .collect(),
        }));
        f.data = Some(Arc::new(record));
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Deserialize)]
    struct Goal {
        order: i32,
        label: String,
    }

    #[derive(Debug, PartialEq, serde::Deserialize)]
    struct Empty {}

    #[test]
    fn arguments_make_the_message_by_name_or_whole() {
        let args = [Value::Int(5), Value::str("x")];
        let g: Goal = message_of("g", &["order", "label"], &args).expect("a goal");
        assert_eq!(
            g,
            Goal {
                order: 5,
                label: "x".into()
            }
        );
        let map = Value::from_json(&serde_json::json!({"order": 2, "label": "y"}));
        let g: Goal = message_of::<_, &str>("g", &[], &[map]).expect("a goal from one map");
        assert_eq!(g.order, 2);
        let e: Empty = message_of::<_, &str>("e", &[], &[]).expect("an empty message");
        assert_eq!(e, Empty {});
    }

    #[test]
    fn arguments_that_do_not_make_the_message_are_a_type_mismatch() {
        let wrong_type = message_of::<Goal, _>(
            "g",
            &["order", "label"],
            &[Value::str("five"), Value::str("x")],
        )
        .expect_err("a string for an i32");
        assert_eq!(wrong_type.exception, "TypeMismatch");
        assert!(wrong_type.message.starts_with("g: "), "{wrong_type:?}");
        let count = message_of::<Goal, _>("g", &["order", "label"], &[Value::Int(1)])
            .expect_err("one argument for two names");
        assert_eq!(count.exception, "TypeMismatch");
        let unnamed = message_of::<Goal, &str>("g", &[], &[Value::Int(1), Value::Int(2)])
            .expect_err("two arguments and no names");
        assert_eq!(unnamed.exception, "TypeMismatch");
        let host = message_of::<Goal, _>("g", &["order"], &[Value::host("Robot", 1_u8)])
            .expect_err("a host value has no JSON form");
        assert!(host.message.contains("argument 1"), "{host:?}");
    }

    #[test]
    fn a_failure_keeps_its_exception_and_carries_its_fields_as_a_record() {
        let f = with_record(
            ActionAborted {
                action: "/fib".into(),
                goal: "00".into(),
                result: serde_json::json!({"sequence": [0, 1]}),
            }
            .raise(),
        );
        assert_eq!(f.exception, "ActionAborted");
        assert!(f.is_a("RosError"));
        let data = f.data::<Value>().expect("a record");
        let Value::Record(r) = &*data else {
            panic!("not a record: {data:?}")
        };
        assert_eq!(&*r.name, "ActionAborted");
        assert_eq!(r.field("action").and_then(Value::as_str), Some("/fib"));
        let result = r.field("result").expect("the result").to_json();
        assert_eq!(result, Ok(serde_json::json!({"sequence": [0, 1]})));
        // Another failure is left as it is.
        let other = with_record(Failure::new("Other", "x"));
        assert!(other.data.is_none());
    }
}
