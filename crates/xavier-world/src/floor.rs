//! The office floor: straight corridors between junctions, numbered rooms whose doors sit on the
//! corridors, the free space the robot may drive in, and shortest paths over the corridor graph.
//! Pure geometry without time; `world.rs` puts the robot, obstacles and mail on it.

use crate::error::{Lost, NoPath, RobotError, UnknownRoom};

/// How far the robot's centre may stray from a corridor's centreline, in metres: corridors are
/// 2 m wide and the robot is 1 m across, which leaves 0.5 m either side. The same margin applies
/// past a corridor's end, so the robot may pull 0.5 m into a corner and no further.
pub const CORRIDOR_CLEARANCE: f64 = 0.5;

/// Half a corridor's width, in metres: an obstacle within this of a centreline is in the corridor.
pub const CORRIDOR_HALF_WIDTH: f64 = 1.0;

/// Tolerance for comparing positions, in metres.
const EPS: f64 = 1e-9;

/// A point on the floor, in metres; x grows to the east, y to the north.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Metres east of the floor's origin (junction A).
    pub x: f64,
    /// Metres north of the floor's origin.
    pub y: f64,
}

/// A point a path goes through: where the robot turns, or the door it is heading for.
pub type Waypoint = Point;

impl Point {
    /// The point `(x, y)`.
    pub const fn new(x: f64, y: f64) -> Point {
        Point { x, y }
    }

    /// Straight-line distance to `other`.
    pub fn distance(self, other: Point) -> f64 {
        (other.x - self.x).hypot(other.y - self.y)
    }
}

/// A named crossing or corner of corridors.
#[derive(Clone, Debug, PartialEq)]
pub struct Junction {
    /// One letter, as on the map in the crate documentation.
    pub name: &'static str,
    /// Where it is.
    pub at: Point,
}

/// A straight, axis-aligned corridor from `from` to `to` (its stations count metres from `from`).
#[derive(Clone, Debug, PartialEq)]
pub struct Corridor {
    /// Its name on the map ("south", "middle", ...).
    pub name: &'static str,
    /// One end.
    pub from: Point,
    /// The other end.
    pub to: Point,
}

impl Corridor {
    /// Its length in metres.
    pub fn length(&self) -> f64 {
        self.from.distance(self.to)
    }

    /// The unit vector from `from` to `to`.
    fn unit(&self) -> (f64, f64) {
        let len = self.length();
        (
            (self.to.x - self.from.x) / len,
            (self.to.y - self.from.y) / len,
        )
    }

    /// How far along the corridor `p` lies (its projection), in metres from `from`.
    pub fn station(&self, p: Point) -> f64 {
        let (ux, uy) = self.unit();
        (p.x - self.from.x) * ux + (p.y - self.from.y) * uy
    }

    /// The point at `station` metres along the centreline.
    pub fn point_at(&self, station: f64) -> Point {
        let (ux, uy) = self.unit();
        Point::new(self.from.x + ux * station, self.from.y + uy * station)
    }

    /// How far `p` lies from the centreline, sideways.
    fn lateral(&self, p: Point) -> f64 {
        let (ux, uy) = self.unit();
        ((p.x - self.from.x) * uy - (p.y - self.from.y) * ux).abs()
    }

    /// The box the robot's centre may occupy in this corridor: `(min, max)` corners.
    fn free_box(&self) -> (Point, Point) {
        let c = CORRIDOR_CLEARANCE;
        (
            Point::new(
                self.from.x.min(self.to.x) - c,
                self.from.y.min(self.to.y) - c,
            ),
            Point::new(
                self.from.x.max(self.to.x) + c,
                self.from.y.max(self.to.y) + c,
            ),
        )
    }

    /// Whether the robot's centre may be at `p` in this corridor.
    fn allows(&self, p: Point) -> bool {
        let (lo, hi) = self.free_box();
        p.x >= lo.x - EPS && p.x <= hi.x + EPS && p.y >= lo.y - EPS && p.y <= hi.y + EPS
    }

    /// From `p` inside the free box, how far along the unit direction `(dx, dy)` the box goes on.
    fn exit_distance(&self, p: Point, (dx, dy): (f64, f64)) -> f64 {
        let (lo, hi) = self.free_box();
        let axis = |pos: f64, d: f64, lo: f64, hi: f64| {
            if d > EPS {
                (hi - pos) / d
            } else if d < -EPS {
                (lo - pos) / d
            } else {
                f64::INFINITY
            }
        };
        axis(p.x, dx, lo.x, hi.x)
            .min(axis(p.y, dy, lo.y, hi.y))
            .max(0.0)
    }

    /// Whether an obstacle at `p` stands in this corridor between stations `a <= b`.
    fn blocked_between(&self, p: Point, a: f64, b: f64) -> bool {
        let s = self.station(p);
        self.lateral(p) <= CORRIDOR_HALF_WIDTH && s >= a - EPS && s <= b + EPS
    }
}

/// A room and where its door is on the map.
#[derive(Clone, Debug, PartialEq)]
pub struct Room {
    /// The number on its door.
    pub number: u32,
    /// The index of the corridor its door opens onto, in [`Floor::corridors`].
    pub corridor: usize,
    /// Where the door is along that corridor, in metres from the corridor's `from` end.
    pub station: f64,
}

/// The office floor: junctions, corridors and rooms. See the map in the crate documentation.
#[derive(Clone, Debug)]
pub struct Floor {
    junctions: Vec<Junction>,
    corridors: Vec<Corridor>,
    rooms: Vec<Room>,
}

impl Floor {
    /// The floor of the crate documentation's map: a 40 m by 20 m loop with a cross corridor and
    /// twelve rooms.
    pub fn office() -> Floor {
        let p = Point::new;
        let junctions = vec![
            Junction {
                name: "A",
                at: p(0.0, 0.0),
            },
            Junction {
                name: "B",
                at: p(20.0, 0.0),
            },
            Junction {
                name: "C",
                at: p(40.0, 0.0),
            },
            Junction {
                name: "D",
                at: p(0.0, 20.0),
            },
            Junction {
                name: "E",
                at: p(20.0, 20.0),
            },
            Junction {
                name: "F",
                at: p(40.0, 20.0),
            },
        ];
        let corridor = |name, from, to| Corridor { name, from, to };
        let corridors = vec![
            corridor("south", p(0.0, 0.0), p(40.0, 0.0)),
            corridor("north", p(0.0, 20.0), p(40.0, 20.0)),
            corridor("west", p(0.0, 0.0), p(0.0, 20.0)),
            corridor("middle", p(20.0, 0.0), p(20.0, 20.0)),
            corridor("east", p(40.0, 0.0), p(40.0, 20.0)),
        ];
        let (south, north, west, middle, east) = (0, 1, 2, 3, 4);
        let room = |number, corridor, station| Room {
            number,
            corridor,
            station,
        };
        let rooms = vec![
            room(1, south, 5.0),
            room(2, north, 6.0),
            room(3, south, 12.0),
            room(4, north, 14.0),
            room(5, south, 27.0),
            room(6, north, 26.0),
            room(7, south, 34.0),
            room(8, north, 33.0),
            room(9, west, 10.0),
            room(10, middle, 6.0),
            room(11, middle, 14.0),
            room(12, east, 10.0),
        ];
        Floor {
            junctions,
            corridors,
            rooms,
        }
    }

    /// The junctions.
    pub fn junctions(&self) -> &[Junction] {
        &self.junctions
    }

    /// The corridors.
    pub fn corridors(&self) -> &[Corridor] {
        &self.corridors
    }

    /// The rooms, in ascending order of number.
    pub fn rooms(&self) -> &[Room] {
        &self.rooms
    }

    /// The room numbered `number`.
    pub fn room(&self, number: u32) -> Result<&Room, UnknownRoom> {
        self.rooms
            .iter()
            .find(|r| r.number == number)
            .ok_or(UnknownRoom { room: number })
    }

    /// Where the map puts the door of room `number` (the real door may be a little off).
    pub fn door(&self, number: u32) -> Result<Point, UnknownRoom> {
        let room = self.room(number)?;
        Ok(self.corridors[room.corridor].point_at(room.station))
    }

    /// Whether the robot's centre may be at `p`.
    pub fn allows(&self, p: Point) -> bool {
        self.corridors.iter().any(|c| c.allows(p))
    }

    /// How far the robot can drive from `p` along the unit direction `dir` before it meets a wall.
    /// Zero if `p` is not in a corridor.
    pub fn free_distance(&self, p: Point, dir: (f64, f64)) -> f64 {
        let mut t = 0.0;
        // Each round moves to the far side of one corridor's box, so the rounds are bounded by the
        // number of corridors (one more to notice that nothing goes further).
        for _ in 0..=self.corridors.len() {
            let here = Point::new(p.x + dir.0 * t, p.y + dir.1 * t);
            let further = self
                .corridors
                .iter()
                .filter(|c| c.allows(here))
                .map(|c| c.exit_distance(here, dir))
                .fold(0.0, f64::max);
            if further <= EPS {
                break;
            }
            t += further;
        }
        t
    }

    /// The shortest route from `from` to the door of `room` over the corridor graph, avoiding every
    /// corridor stretch that has one of `blocked` in it. Returns the turning points and the door,
    /// not `from` itself; empty if the robot is already there.
    pub fn plan(
        &self,
        from: Point,
        room: u32,
        blocked: &[Point],
    ) -> Result<Vec<Waypoint>, RobotError> {
        let goal_idx = self
            .rooms
            .iter()
            .position(|r| r.number == room)
            .ok_or(UnknownRoom { room })?;
        // Nodes: the junctions, then the doors, then the start.
        let n_junctions = self.junctions.len();
        let mut nodes: Vec<Point> = self.junctions.iter().map(|j| j.at).collect();
        for r in &self.rooms {
            nodes.push(self.corridors[r.corridor].point_at(r.station));
        }
        let start = nodes.len();
        nodes.push(from);
        let goal = n_junctions + goal_idx;

        let mut edges: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nodes.len()];
        let mut on_map = false;
        for (c_idx, c) in self.corridors.iter().enumerate() {
            let mut stations: Vec<(f64, usize)> = Vec::new();
            for (j_idx, j) in self.junctions.iter().enumerate() {
                if c.lateral(j.at) <= EPS {
                    stations.push((c.station(j.at), j_idx));
                }
            }
            for (r_idx, r) in self.rooms.iter().enumerate() {
                if r.corridor == c_idx {
                    stations.push((r.station, n_junctions + r_idx));
                }
            }
            if c.allows(from) {
                on_map = true;
                stations.push((c.station(from), start));
            }
            stations.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for pair in stations.windows(2) {
                let ((sa, a), (sb, b)) = (pair[0], pair[1]);
                if a != b && !blocked.iter().any(|&o| c.blocked_between(o, sa, sb)) {
                    edges[a].push((b, sb - sa));
                    edges[b].push((a, sb - sa));
                }
            }
        }
        if !on_map {
            return Err(Lost {
                x: from.x,
                y: from.y,
            }
            .into());
        }
        let route = shortest(&edges, start, goal).ok_or(NoPath { room })?;
        Ok(waypoints(
            &route.iter().map(|&n| nodes[n]).collect::<Vec<_>>(),
        ))
    }
}

/// Dijkstra's shortest path from `start` to `goal`; ties go to the lower node index, so the result
/// is the same on every run.
fn shortest(edges: &[Vec<(usize, f64)>], start: usize, goal: usize) -> Option<Vec<usize>> {
    let n = edges.len();
    let mut dist = vec![f64::INFINITY; n];
    let mut prev: Vec<Option<usize>> = vec![None; n];
    let mut done = vec![false; n];
    dist[start] = 0.0;
    for _ in 0..n {
        let next = (0..n)
            .filter(|&i| !done[i] && dist[i].is_finite())
            .min_by(|&a, &b| dist[a].total_cmp(&dist[b]).then(a.cmp(&b)))?;
        if next == goal {
            break;
        }
        done[next] = true;
        for &(to, w) in &edges[next] {
            if dist[next] + w < dist[to] {
                dist[to] = dist[next] + w;
                prev[to] = Some(next);
            }
        }
    }
    if !dist[goal].is_finite() {
        return None;
    }
    let mut route = vec![goal];
    let mut at = goal;
    // A predecessor chain visits each node at most once, so it is at most `n` long.
    for _ in 0..n {
        match prev[at] {
            Some(p) => {
                route.push(p);
                at = p;
            }
            None => break,
        }
    }
    route.reverse();
    Some(route)
}

/// Keeps the points where the route turns, and its end; drops the start and the points it passes
/// straight through.
fn waypoints(route: &[Point]) -> Vec<Waypoint> {
    let mut out: Vec<Point> = Vec::new();
    let mut last = match route.first() {
        Some(&p) => p,
        None => return out,
    };
    for (i, &p) in route.iter().enumerate().skip(1) {
        if p.distance(last) <= EPS {
            continue;
        }
        let straight_on = route.get(i + 1).is_some_and(|&next| {
            let cross = (p.x - last.x) * (next.y - p.y) - (p.y - last.y) * (next.x - p.x);
            let dot = (p.x - last.x) * (next.x - p.x) + (p.y - last.y) * (next.y - p.y);
            cross.abs() <= EPS && dot >= 0.0
        });
        if !straight_on {
            out.push(p);
            last = p;
        }
    }
    out
}

#[cfg(test)]
mod tests;
