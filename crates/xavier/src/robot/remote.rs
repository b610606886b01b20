//! The robot of a robot agent in another process, reached over zenoh (the feature
//! `distributed`): the executive's side ([`RemoteRobot`]: the commands as remote tasks placed on
//! the robot agent, `speak` on the voice agent, and the queries that are no nodes), and the
//! agent's ([`serve`], [`serve_queries`]); the world's values cross as JSON.

use serde_json::{Value, json};
use std::sync::{Mutex, PoisonError};
use std::time::Duration;
use tcm::{Exception, Failure, Task};
use tcm_zenoh::{AgentBuilder, At, Executive, RemoteCtx, RemoteError, RemoteFailure};
use xavier_world::{Point, Pose, SharedWorld, Summary, Waypoint, speech_duration};

/// How long a query to the robot agent may take.
const QUERY_TIMEOUT: Duration = Duration::from_secs(10);

/// A robot served by agents: the executive that places the commands, the agent that holds the
/// world, and the one that speaks.
pub struct RemoteRobot {
    exec: Executive,
    body: String,
    voice: String,
    summary: Mutex<Option<Summary>>,
}

impl std::fmt::Debug for RemoteRobot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteRobot")
            .field("system", &self.exec.system())
            .field("body", &self.body)
            .field("voice", &self.voice)
            .finish()
    }
}

/// The key of the robot agent's query `what` in `system`.
pub fn query_key(system: &str, what: &str) -> String {
    format!("tdl/{system}/xavier/{what}")
}
impl RemoteRobot {
    /// Asks the robot agent `what`, with `payload`; its JSON answer.
    async fn query(&self, what: &str, payload: Vec<u8>) -> Result<Value, Failure> {
        // On the executive's runtime: a journaled run's tree runs on a current-thread one.
        let (session, key) = (
            self.exec.session().clone(),
            query_key(self.exec.system(), what),
        );
        let bytes = self
            .exec
            .on_runtime(async move { query(&session, &key, payload).await })
            .await
            .map_err(|e| remote_error(e.to_string()))?
            .map_err(remote_error)?;
        serde_json::from_slice(&bytes)
            .map_err(|e| remote_error(format!("the robot's answer to {what} is not JSON: {e}")))
    }
}

/// Sends query `key` with `payload` and returns the first reply's bytes.
pub async fn query(
    session: &zenoh::Session,
    key: &str,
    payload: Vec<u8>,
) -> Result<Vec<u8>, String> {
    let replies = session
        .get(key)
        .payload(payload)
        .timeout(QUERY_TIMEOUT)
        .await
        .map_err(|e| format!("query {key}: {e}"))?;
    let reply = replies
        .recv_async()
        .await
        .map_err(|_| format!("query {key}: no answer within {QUERY_TIMEOUT:?}"))?;
    match reply.result() {
        Ok(sample) => Ok(sample.payload().to_bytes().to_vec()),
        Err(e) => Err(format!(
            "query {key}: {}",
            String::from_utf8_lossy(&e.payload().to_bytes())
        )),
    }
}

fn remote_error(message: impl Into<String>) -> Failure {
    RemoteError {
        message: message.into(),
    }
    .raise()
}

// --- the mission's commands --------------------------------------------------------------------

impl RemoteRobot {
    /// The robot of agent `body`, and of agent `voice` for `speak`, through `exec`.
    pub(super) fn new(exec: Executive, body: &str, voice: &str) -> RemoteRobot {
        RemoteRobot {
            exec,
            body: body.to_string(),
            voice: voice.to_string(),
            summary: Mutex::new(None),
        }
    }

    pub(super) async fn pose(&self) -> Result<Pose, Failure> {
        pose_of(&self.query("pose", Vec::new()).await?).map_err(remote_error)
    }

    pub(super) async fn motor_temperature(&self) -> Result<f64, Failure> {
        self.query("motor_temperature", Vec::new())
            .await?
            .as_f64()
            .ok_or_else(|| remote_error("the motor temperature is not a number"))
    }

    pub(super) fn summary(&self) -> Summary {
        self.summary
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
            .unwrap_or(Summary {
                delivered: Vec::new(),
                utterances: 0,
                distance_travelled: 0.0,
                time: Duration::ZERO,
            })
    }

    pub(super) async fn fetch_summary(&self) -> Result<(), Failure> {
        let s = summary_of(&self.query("summary", Vec::new()).await?).map_err(remote_error)?;
        *self.summary.lock().unwrap_or_else(PoisonError::into_inner) = Some(s);
        Ok(())
    }

    pub(super) fn plan_path(&self, room: u32) -> Task {
        self.exec
            .remote(At::agent(&self.body), "planPath", room)
            .task_map_journaled(|v| path_of(&v), |p: &Vec<Waypoint>| path_json(p))
    }

    /// The command `name` on the robot agent, its value read as a `T`.
    pub(super) fn command<T, A>(&self, name: &str, arg: A) -> Task
    where
        T: serde::Serialize + serde::de::DeserializeOwned + Send + 'static,
        A: serde::Serialize,
    {
        self.exec
            .remote(At::agent(&self.body), name, arg)
            .typed_task::<T>()
    }

    pub(super) fn speak(&self, text: String) -> Task {
        self.exec
            .remote(At::agent(&self.voice), "speak", text)
            .typed_task::<()>()
    }
}

// --- JSON of the world's values ----------------------------------------------------------------

fn num(v: &Value, field: &str) -> Result<f64, String> {
    v.get(field)
        .and_then(Value::as_f64)
        .ok_or_else(|| format!("no number {field} in {v}"))
}

fn point_json(p: &Point) -> Value {
    json!({"x": p.x, "y": p.y})
}

fn path_of(v: &Value) -> Result<Vec<Waypoint>, String> {
    v.as_array()
        .ok_or_else(|| format!("a path is a list of points, not {v}"))?
        .iter()
        .map(|p| Ok(Point::new(num(p, "x")?, num(p, "y")?)))
        .collect()
}

fn path_json(path: &[Waypoint]) -> Value {
    Value::Array(path.iter().map(point_json).collect())
}

fn pose_json(p: &Pose) -> Value {
    json!({"x": p.x, "y": p.y, "heading": p.heading})
}

fn pose_of(v: &Value) -> Result<Pose, String> {
    Ok(Pose {
        x: num(v, "x")?,
        y: num(v, "y")?,
        heading: num(v, "heading")?,
    })
}

fn summary_json(s: &Summary) -> Value {
    json!({
        "delivered": s.delivered,
        "utterances": s.utterances,
        "distance_travelled": s.distance_travelled,
        "time_s": s.time.as_secs_f64(),
    })
}

fn summary_of(v: &Value) -> Result<Summary, String> {
    let delivered = v
        .get("delivered")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("no delivered rooms in {v}"))?
        .iter()
        .map(|r| {
            r.as_u64()
                .and_then(|r| u32::try_from(r).ok())
                .ok_or_else(|| format!("not a room: {r}"))
        })
        .collect::<Result<Vec<u32>, String>>()?;
    let utterances = v
        .get("utterances")
        .and_then(Value::as_u64)
        .and_then(|n| usize::try_from(n).ok())
        .ok_or_else(|| format!("no utterances in {v}"))?;
    let time = num(v, "time_s")?;
    Ok(Summary {
        delivered,
        utterances,
        distance_travelled: num(v, "distance_travelled")?,
        time: Duration::try_from_secs_f64(time).map_err(|e| format!("time {time}: {e}"))?,
    })
}

// --- the robot agent ---------------------------------------------------------------------------

/// A world's failure as it travels: its exception's name, message and ancestry.
fn failed(e: xavier_world::RobotError) -> RemoteFailure {
    RemoteFailure::from_failure(&Failure::from(e))
}

/// `builder` offering the robot's commands on `world`, each under its local task's name.
/// `speak` is offered too, so the robot can speak itself when no voice agent is there.
pub fn serve(world: &SharedWorld, builder: AgentBuilder) -> AgentBuilder {
    let (w1, w2, w3, w4, w5, w6, w7) = (
        world.clone(),
        world.clone(),
        world.clone(),
        world.clone(),
        world.clone(),
        world.clone(),
        world.clone(),
    );
    builder
        .command("planPath", move |_: RemoteCtx, room: u32| {
            let w = w1.clone();
            async move {
                let path = w.plan_path(room).await.map_err(failed)?;
                Ok::<_, RemoteFailure>(Value::Array(path.iter().map(point_json).collect()))
            }
        })
        .command("turn", move |_: RemoteCtx, angle: f64| {
            let w = w2.clone();
            async move { w.turn(angle).await.map_err(failed) }
        })
        .command("guardedMove", move |_: RemoteCtx, dist: f64| {
            let w = w3.clone();
            async move { w.guarded_move(dist).await.map_err(failed) }
        })
        .command("lookForDoor", move |_: RemoteCtx, room: u32| {
            let w = w4.clone();
            async move { w.look_for_door(room).await.map_err(failed) }
        })
        .command("speak", move |_: RemoteCtx, text: String| {
            let w = w5.clone();
            async move {
                w.speak(&text).await;
                Ok::<_, RemoteFailure>(())
            }
        })
        .command("mailGone", move |_: RemoteCtx, room: u32| {
            let w = w6.clone();
            async move { w.mail_gone(room).await.map_err(failed) }
        })
        .command("motorTemperature", move |_: RemoteCtx, (): ()| {
            let w = w7.clone();
            async move { Ok::<_, RemoteFailure>(w.motor_temperature().await) }
        })
}

/// The robot agent's queries (see the module's documentation), on its `session`, for `system`;
/// `scale` is the world's time scale (`SharedWorld::scaled`). Keep the queryables: dropped, they
/// are withdrawn.
pub async fn serve_queries(
    session: &zenoh::Session,
    system: &str,
    world: &SharedWorld,
    scale: f64,
) -> Result<Vec<zenoh::query::Queryable<()>>, zenoh::Error> {
    let rt = tokio::runtime::Handle::current();
    let mut out = Vec::new();
    for what in ["pose", "motor_temperature", "hear", "summary"] {
        let (world, rt) = (world.clone(), rt.clone());
        let q = session
            .declare_queryable(query_key(system, what))
            .callback(move |query| {
                let world = world.clone();
                rt.spawn(async move {
                    let answer = match what {
                        "pose" => pose_json(&world.inspect(|w| w.pose())),
                        "motor_temperature" => json!(world.motor_temperature().await),
                        "hear" => {
                            let text = query
                                .payload()
                                .map(|p| String::from_utf8_lossy(&p.to_bytes()).into_owned())
                                .unwrap_or_default();
                            world.synced(|w| w.speak(&text));
                            json!(speech_duration(&text).as_secs_f64() / scale)
                        }
                        _ => summary_json(&world.summary()),
                    };
                    let key = query.key_expr().clone();
                    if let Err(e) = query.reply(key, answer.to_string()).await {
                        eprintln!("xavier-robot: cannot answer {what}: {e}");
                    }
                });
            })
            .await?;
        out.push(q);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_worlds_values_round_trip_through_json() {
        let path = vec![Point::new(1.0, 2.5), Point::new(-3.0, 0.0)];
        let v = Value::Array(path.iter().map(point_json).collect());
        assert_eq!(path_of(&v), Ok(path));
        let pose = Pose {
            x: 1.0,
            y: 2.0,
            heading: -0.5,
        };
        assert_eq!(pose_of(&pose_json(&pose)), Ok(pose));
        let s = Summary {
            delivered: vec![3, 7],
            utterances: 4,
            distance_travelled: 61.5,
            time: Duration::from_millis(152_300),
        };
        assert_eq!(summary_of(&summary_json(&s)), Ok(s));
        assert!(path_of(&json!({"x": 1})).is_err());
        assert!(pose_of(&json!({"x": 1, "y": 2})).is_err());
    }
}
