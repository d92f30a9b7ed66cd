//! The episode as a 3D scene a person can turn, for `report.html`: the hand's links and
//! fingertips from our forward kinematics, the object and the table from the scene, the
//! contacts and forces, the goals, with a time slider and a play button. The positions are
//! computed here (the page's script needs no kinematics) and embedded as JSON in a
//! `<script type="application/json">`; the drawing is three.js, vendored at a pinned version
//! (`host/report/vendor/three/`, `scripts/vendor-three.sh`) and inlined, gzip-compressed in
//! base64 (the page inflates it with the browser's `DecompressionStream`), with the viewer
//! (`scene3d.js`), so the page works offline from a `file://` URL.

use dips_world::geometry::PartShape;
use dips_world::kinematics::Finger;
use dips_world::scenes::{SceneKind, card, screwdriver};
use dips_world::world::World;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::ReportError;
use crate::recording::Recording;

/// three.js (the parts the viewer uses, and OrbitControls), bundled as one classic script
/// that defines the global `DIPS_THREE`; pages carry it as [`THREE_JS_GZ`].
pub const THREE_JS: &str = include_str!("../vendor/three/three-dips.min.js");
/// [`THREE_JS`] gzip-compressed (`gzip -9n`, by `scripts/vendor-three.sh`): what a page
/// carries, in base64, a quarter of the size.
pub const THREE_JS_GZ: &[u8] = include_bytes!("../vendor/three/three-dips.min.js.gz");
/// The `id` of the `<script type="text/plain">` holding [`THREE_JS_GZ`] in base64.
pub const THREE_ID: &str = "dips-three-gz";
/// The version of three.js in [`THREE_JS`].
pub const THREE_VERSION: &str = "0.187.0";
/// three.js's licence (MIT), kept beside the vendored file.
pub const THREE_LICENSE: &str = include_str!("../vendor/three/LICENSE");
/// The viewer: reads the scene data and draws it with [`THREE_JS`].
pub const VIEWER_JS: &str = include_str!("scene3d.js");
/// The `id` of the `<script type="application/json">` holding the [`SceneData`].
pub const DATA_ID: &str = "dips-scene-data";

/// Metres of force arrow per newton in the 3D view: ten times the three-view drawings'
/// (`crate::render::FORCE_SCALE`), since the fingers' forces are mostly 0.05–0.5 N and a
/// millimetre-long arrow is lost in a view that turns.
pub const FORCE_SCALE_3D: f64 = 0.05;

/// Points per finger in [`FrameData::hand`]: the hand's base, the four joint origins and the
/// fingertip sphere's centre.
pub const POINTS_PER_FINGER: usize = 6;

/// Positions are written in metres rounded to this (0.01 mm), quaternions likewise.
const ROUND: f64 = 1e5;

fn round(x: f64) -> f64 {
    (x * ROUND).round() / ROUND
}

fn p3(p: &Point3<f64>) -> [f64; 3] {
    [round(p.x), round(p.y), round(p.z)]
}

/// An object pose as position and quaternion: `[x, y, z, qx, qy, qz, qw]`.
fn pose7(pose: &Isometry3<f64>) -> [f64; 7] {
    let t = pose.translation.vector;
    let q = pose.rotation.coords; // (i, j, k, w)
    [
        round(t.x),
        round(t.y),
        round(t.z),
        round(q.x),
        round(q.y),
        round(q.z),
        round(q.w),
    ]
}

/// One finger of the hand: its name, whether the task uses it, its colour.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FingerData {
    /// `index`, `middle`, `ring` or `thumb`.
    pub name: String,
    /// Whether the task's modes use this finger.
    pub task: bool,
    /// Its colour (`#rrggbb`), the plots' colour of the finger.
    pub color: String,
}

/// A part of the object or the table in its body's frame (as `dips_world::geometry::PartShape`).
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(tag = "shape", rename_all = "lowercase")]
pub enum PartData {
    /// A box centred at `center` with `half` extents, axis-aligned in the body frame.
    Box {
        /// Centre (m).
        center: [f64; 3],
        /// Half extents (m).
        half: [f64; 3],
    },
    /// A solid cylinder along the body's +z from `z0` to `z1`.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Bottom (m).
        z0: f64,
        /// Top (m).
        z1: f64,
    },
}

/// One world state of the recording.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FrameData {
    /// For each finger in [`SceneData::fingers`]' order, [`POINTS_PER_FINGER`] points
    /// (`x, y, z` in metres, world frame, flattened): the base, the joint origins, the tip.
    pub hand: Vec<f64>,
    /// The object's pose `[x, y, z, qx, qy, qz, qw]`.
    pub object: [f64; 7],
    /// Contacts: `[px, py, pz, fx, fy, fz]`, point (m) and the force exerted on the object (N).
    pub contacts: Vec<[f64; 6]>,
    /// Indices into [`SceneData::goals`] drawn with this state.
    pub goals: Vec<usize>,
    /// Seconds the state is shown when playing (as in the animation).
    pub hold_s: f64,
    /// What the state is: mode, step, time, the object against its goal.
    pub label: String,
}

/// A goal pose of the object, drawn as a ghost.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GoalData {
    /// The pose `[x, y, z, qx, qy, qz, qw]`.
    pub pose: [f64; 7],
    /// What the goal is, with its coordinate.
    pub label: String,
}

/// Everything the viewer draws.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SceneData {
    /// `screwdriver` or `card`.
    pub scene: String,
    /// The recording's title.
    pub title: String,
    /// The fingers, in the order of [`FrameData::hand`].
    pub fingers: Vec<FingerData>,
    /// The fingertip spheres' radius (m).
    pub tip_radius: f64,
    /// The object's parts in its frame.
    pub object: Vec<PartData>,
    /// The screwdriver's yaw marker in the object frame: a line across the cap along the
    /// handle's x axis, drawn with a dot at its second end.
    pub marker: Option<[[f64; 3]; 2]>,
    /// The object's reference point in its frame (the screwdriver's cap, the card's centre),
    /// whose path is drawn.
    pub reference: [f64; 3],
    /// The table (world frame), if the scene has one.
    pub table: Option<PartData>,
    /// Metres of arrow per newton.
    pub force_scale: f64,
    /// The goals of the episode.
    pub goals: Vec<GoalData>,
    /// The states, in order.
    pub frames: Vec<FrameData>,
}

/// The object pose of task coordinates `coords` (the card at its resting height), as the
/// three-view drawings place a goal.
fn goal_pose(scene: SceneKind, coords: [f64; 3]) -> Isometry3<f64> {
    match scene {
        SceneKind::Screwdriver => Isometry3::from_parts(
            Translation3::from(screwdriver::pivot().coords),
            UnitQuaternion::from_rotation_matrix(&screwdriver::rotation(
                coords[0], coords[1], coords[2],
            )),
        ),
        SceneKind::Card => Isometry3::from_parts(
            Translation3::new(coords[0], coords[1], card::INITIAL_CENTER[2]),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), coords[2]),
        ),
    }
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// The hand's points of one world state: per finger (in [`Finger::ALL`]'s order) the base,
/// the four joint origins and the fingertip centre, from the hand model's forward kinematics.
pub fn hand_points(world: &World) -> Vec<Point3<f64>> {
    let hand = world.hand_model();
    let base = world.hand_base();
    let q = world.joints();
    let base_p = Point3::from(base.translation.vector);
    let mut out = Vec::with_capacity(4 * POINTS_PER_FINGER);
    for f in Finger::ALL {
        let frames = hand.finger_frames(&base, f, &q[f.index()]);
        out.push(base_p);
        out.extend(frames.joint_origins);
        out.push(frames.tip_center);
    }
    out
}

/// The scene data of a recording: every frame's hand points from our kinematics, the object
/// pose, contacts and goals. A state the world refuses (a wrong length, a non-finite value)
/// is drawn as the state before it, its label saying why, so that the report of such an
/// episode is still written; only a recording with no state is an error.
pub fn scene_data(rec: &Recording) -> Result<SceneData, ReportError> {
    if rec.frames.is_empty() {
        return Err(ReportError::Input {
            path: rec.title.clone(),
            reason: "holds no states; nothing to draw".into(),
        });
    }
    let scene = rec.scene;
    let mut world = World::new(scene);
    let task = scene.task_fingers();
    let fingers = Finger::ALL
        .iter()
        .map(|&f| FingerData {
            name: f.name().to_string(),
            task: task.contains(&f),
            color: hex(if task.contains(&f) {
                crate::pictures::finger_color(f)
            } else {
                [110, 120, 150]
            }),
        })
        .collect();
    let part = |shape: &PartShape| match *shape {
        PartShape::Box {
            center,
            half_extents,
        } => PartData::Box {
            center,
            half: half_extents,
        },
        PartShape::Cylinder { radius, z0, z1 } => PartData::Cylinder { radius, z0, z1 },
    };
    let object = world
        .object_body()
        .parts
        .iter()
        .map(|p| part(&p.shape))
        .collect();
    let (marker, reference, table) = match scene {
        SceneKind::Screwdriver => {
            let (r, z) = (screwdriver::CAP_RADIUS, screwdriver::CAP_Z1);
            (
                Some([[-r, 0.0, z], [r, 0.0, z]]),
                screwdriver::CAP_ORIGIN,
                None,
            )
        }
        SceneKind::Card => (
            None,
            [0.0; 3],
            Some(PartData::Box {
                center: card::TABLE_CENTER,
                half: card::TABLE_HALF_EXTENTS,
            }),
        ),
    };
    let mut goals: Vec<GoalData> = Vec::new();
    let mut frames = Vec::with_capacity(rec.frames.len());
    for (k, frame) in rec.frames.iter().enumerate() {
        let refused = world.set_state(&frame.state).err();
        let hand = hand_points(&world).iter().flat_map(p3).collect();
        let mut goal_ids = Vec::with_capacity(frame.goals.len());
        for g in &frame.goals {
            let label = match scene {
                SceneKind::Screwdriver => format!("{} yaw {:.2} rad", g.label, g.coords[2]),
                SceneKind::Card => format!("{} y {:.1} cm", g.label, 100.0 * g.coords[1]),
            };
            let pose = pose7(&goal_pose(scene, g.coords));
            let id = match goals
                .iter()
                .position(|x| x.pose == pose && x.label == label)
            {
                Some(i) => i,
                None => {
                    goals.push(GoalData { pose, label });
                    goals.len() - 1
                }
            };
            goal_ids.push(id);
        }
        frames.push(FrameData {
            hand,
            object: pose7(&world.object().pose()),
            contacts: frame
                .contacts
                .iter()
                .map(|c| {
                    let r = |x: f64| (x * 1e4).round() / 1e4;
                    [
                        round(c.point[0]),
                        round(c.point[1]),
                        round(c.point[2]),
                        r(c.force[0]),
                        r(c.force[1]),
                        r(c.force[2]),
                    ]
                })
                .collect(),
            goals: goal_ids,
            hold_s: frame.hold_s,
            label: match refused {
                None => frame.label.clone(),
                Some(e) => format!(
                    "{} · state {k} not drawn ({e}); the previous one is",
                    frame.label
                ),
            },
        });
    }
    Ok(SceneData {
        scene: scene.name().to_string(),
        title: rec.title.clone(),
        fingers,
        tip_radius: world.hand_model().tip_radius,
        object,
        marker,
        reference,
        table,
        force_scale: FORCE_SCALE_3D,
        goals,
        frames,
    })
}

/// Standard base64 (RFC 4648, with padding): only `A–Z a–z 0–9 + / =`, safe in any element.
pub fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(char::from(ABC[(n >> (18 - 6 * i)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// JSON that is safe inside a `<script>` element: `<`, `>` and `&` are written as `\u` escapes
/// (JSON strings allow them; the text can then never close the element).
fn script_safe_json(data: &SceneData) -> String {
    let json = serde_json::to_string(data).unwrap_or_else(|_| "null".into());
    json.replace('<', "\\u003c")
        .replace('>', "\\u003e")
        .replace('&', "\\u0026")
}

/// The markup of the 3D view: the canvas's box, the controls (play button, time slider, the
/// state's words), the data, three.js and the viewer.
pub fn scene_html(data: &SceneData) -> String {
    let n = data.frames.len();
    format!(
        "<div id=\"dips-scene\" class=\"scene3d\" data-frames=\"{n}\" data-frame=\"0\">\n\
         <div class=\"scene3d-view\" id=\"dips-scene-view\"></div>\n\
         <div class=\"scene3d-controls\">\
         <button type=\"button\" id=\"dips-scene-play\">▶ play</button> \
         <input type=\"range\" id=\"dips-scene-slider\" min=\"0\" max=\"{max}\" value=\"0\" step=\"1\" \
         aria-label=\"state\"> \
         <button type=\"button\" id=\"dips-scene-reset\">reset view</button>\
         </div>\n\
         <p class=\"scene3d-label\" id=\"dips-scene-label\">{label}</p>\n\
         <noscript><p class=\"note\">The 3D view needs JavaScript.</p></noscript>\n\
         </div>\n\
         <script type=\"application/json\" id=\"{DATA_ID}\">{json}</script>\n\
         <script type=\"text/plain\" id=\"{THREE_ID}\">{three}</script>\n\
         <script>\n{VIEWER_JS}\n</script>\n",
        max = n.saturating_sub(1),
        label = crate::html::escape(data.frames.first().map_or("", |f| f.label.as_str())),
        json = script_safe_json(data),
        three = base64(THREE_JS_GZ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::Frame;

    fn recording(scene: SceneKind, states: Vec<Vec<f64>>) -> Recording {
        Recording {
            scene,
            title: "test".into(),
            frames: states
                .into_iter()
                .enumerate()
                .map(|(k, state)| Frame {
                    state,
                    contacts: Vec::new(),
                    goals: vec![crate::render::Goal {
                        coords: [0.0, 0.0, -1.0],
                        label: "mode goal".into(),
                    }],
                    label: format!("state {k} <&>"),
                    hold_s: 0.4,
                })
                .collect(),
            episode: None,
        }
    }

    #[test]
    fn hand_points_are_our_forward_kinematics() {
        for scene in SceneKind::ALL {
            let mut world = World::new(scene);
            let mut state = world.state();
            // Bend every finger's joints by known amounts, within their limits.
            for (i, f) in scene.task_fingers().iter().enumerate() {
                let lim = world.hand_model().joint_limits(*f);
                for (j, (lo, hi)) in lim.iter().enumerate() {
                    state[4 * i + j] = lo + (hi - lo) * (0.2 + 0.15 * j as f64);
                }
            }
            let rec = recording(scene, vec![world.state(), state.clone()]);
            let data = scene_data(&rec).unwrap();
            assert_eq!(data.frames.len(), 2);
            world.set_state(&state).unwrap();
            let q = world.joints();
            let base = world.hand_base();
            let hand = world.hand_model().clone();
            let got = &data.frames[1].hand;
            assert_eq!(got.len(), 4 * POINTS_PER_FINGER * 3);
            for (i, f) in Finger::ALL.iter().enumerate() {
                let fr = hand.finger_frames(&base, *f, &q[f.index()]);
                let mut want = vec![Point3::from(base.translation.vector)];
                want.extend(fr.joint_origins);
                want.push(fr.tip_center);
                // The fingertip is where the world says it is.
                assert!((fr.tip_center - world.tip_centers()[f.index()]).norm() < 1e-12);
                for (k, p) in want.iter().enumerate() {
                    let o = 3 * (i * POINTS_PER_FINGER + k);
                    for d in 0..3 {
                        assert!(
                            (got[o + d] - p[d]).abs() <= 0.6 / ROUND,
                            "{scene:?} {f:?} point {k} axis {d}: {} vs {}",
                            got[o + d],
                            p[d]
                        );
                    }
                }
            }
            // A state the world refuses keeps the previous one, and says so.
            let mut bad = state.clone();
            bad[0] = f64::NAN;
            let rec = recording(scene, vec![state.clone(), bad]);
            let kept = scene_data(&rec).unwrap();
            assert_eq!(kept.frames[1].hand, kept.frames[0].hand);
            assert!(kept.frames[1].label.contains("not drawn"));
            // Bending the joints moved the fingertips.
            assert_ne!(data.frames[0].hand, data.frames[1].hand);
            // The object's pose is the world's.
            let pose = world.object().pose();
            assert!((data.frames[1].object[2] - pose.translation.vector.z).abs() < 1e-5);
            assert_eq!(data.goals.len(), 1);
            assert_eq!(data.frames[1].goals, vec![0]);
        }
    }

    #[test]
    fn a_published_episode_report_has_the_3d_view_of_every_state() {
        let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../docs/results/card/episodes/dips/seed-3008/result.json");
        let dir = std::env::temp_dir().join(format!("dips-report-3d-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::copy(&src, dir.join("result.json")).unwrap();
        let rec = Recording::read(&dir.join("result.json")).unwrap();
        crate::write_episode_report(&dir, &rec, false, &mut |_, _| {}).unwrap();
        let html = std::fs::read_to_string(dir.join(crate::REPORT_HTML)).unwrap();
        assert!(html.contains("<h2 id=\"scene3d\">3D view</h2>"));
        assert!(html.contains(&base64(THREE_JS_GZ)) && html.contains(VIEWER_JS));
        let start = html.find(DATA_ID).unwrap() + DATA_ID.len() + 2;
        let end = start + html[start..].find("</script>").unwrap();
        let data: serde_json::Value = serde_json::from_str(&html[start..end]).unwrap();
        let frames = data["frames"].as_array().unwrap();
        assert_eq!(frames.len(), rec.frames.len());
        // Contacts and forces are carried; every state has its hand and object.
        assert!(
            frames
                .iter()
                .any(|f| !f["contacts"].as_array().unwrap().is_empty())
        );
        assert!(
            frames
                .iter()
                .all(|f| f["hand"].as_array().unwrap().len() == 72)
        );
        // The card's last state: the hand where our kinematics puts it.
        let mut world = World::new(SceneKind::Card);
        world.set_state(&rec.frames.last().unwrap().state).unwrap();
        let tips = world.tip_centers();
        let last = frames.last().unwrap()["hand"].as_array().unwrap();
        for f in Finger::ALL {
            let o = 3 * (f.index() * POINTS_PER_FINGER + POINTS_PER_FINGER - 1);
            for d in 0..3 {
                assert!((last[o + d].as_f64().unwrap() - tips[f.index()][d]).abs() < 1e-5);
            }
        }
        for f in crate::html::referenced_files(&html) {
            assert!(dir.join(&f).is_file(), "missing {f}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// CRC-32 (IEEE), as gzip's trailer holds it.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    (c >> 1) ^ 0xEDB8_8320
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    #[test]
    fn the_compressed_library_is_the_vendored_one_and_base64_is_standard() {
        // gzip: magic, deflate; the trailer's CRC-32 and size are those of THREE_JS.
        let gz = THREE_JS_GZ;
        assert_eq!(&gz[..3], &[0x1f, 0x8b, 8]);
        let n = gz.len();
        let crc = u32::from_le_bytes(gz[n - 8..n - 4].try_into().unwrap());
        let size = u32::from_le_bytes(gz[n - 4..].try_into().unwrap());
        assert_eq!(size as usize, THREE_JS.len());
        assert_eq!(crc, crc32(THREE_JS.as_bytes()));
        assert!(gz.len() * 3 < THREE_JS.len());
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded);
        }
        assert_eq!(base64(&[0xfb, 0xff, 0xbf]), "+/+/");
    }

    #[test]
    fn the_markup_holds_the_data_three_and_the_viewer_safely() {
        let world = World::new(SceneKind::Card);
        let rec = recording(SceneKind::Card, vec![world.state(); 3]);
        let data = scene_data(&rec).unwrap();
        let html = scene_html(&data);
        assert!(html.contains(&format!(
            "<script type=\"application/json\" id=\"{DATA_ID}\">"
        )));
        assert!(html.contains(&format!(
            "<script type=\"text/plain\" id=\"{THREE_ID}\">{}</script>",
            base64(THREE_JS_GZ)
        )));
        assert!(THREE_JS.contains("DIPS_THREE"));
        assert!(THREE_JS.contains(THREE_VERSION) && THREE_LICENSE.contains("MIT"));
        assert!(html.contains(VIEWER_JS));
        assert!(html.contains("max=\"2\""));
        // The data round-trips, and no label can close its script element.
        let start = html.find(DATA_ID).unwrap() + DATA_ID.len() + 2;
        let end = start + html[start..].find("</script>").unwrap();
        let back: serde_json::Value = serde_json::from_str(&html[start..end]).unwrap();
        assert_eq!(back["frames"][1]["label"], "state 1 <&>");
        assert_eq!(back, serde_json::to_value(&data).unwrap());
        assert!(!html[start..end].contains('<'));
        // Nothing in the page refers to another file or the network.
        assert!(crate::html::referenced_files(&html).is_empty());
    }
}
