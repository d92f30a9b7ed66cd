//! The contact-model options measured for issue 10 (`docs/world.md`, "Contact without action
//! at a distance"): prints the table there. A measurement, not a check; run with
//! `cargo test --release -p dips-world --test contact_model_options -- --ignored --nocapture`.
use dips_world::kinematics::{Finger, HandModel};
use dips_world::scenes::{SceneKind, screwdriver};
use dips_world::world::{
    CommandProfile, ConeActivation, FrictionModel, World, WorldParams, scripted,
};
use nalgebra::{Point3, Vector3};

/// A named way to change the world's parameters.
type Variant = (&'static str, Box<dyn Fn(&mut WorldParams)>);

fn world(scene: SceneKind, opt: &dyn Fn(&mut WorldParams)) -> World {
    let mut p = WorldParams::for_scene(scene);
    opt(&mut p);
    World::with_model(scene, HandModel::allegro_v4(), p).unwrap()
}
fn back_off(w: &mut World, gap: f64) {
    let dq = scripted::back_off_action(w, gap);
    w.step_action(&dq).unwrap();
}
fn graze(opt: &dyn Fn(&mut WorldParams), gap: f64) -> f64 {
    let mut w = world(SceneKind::Screwdriver, opt);
    back_off(&mut w, gap);
    let y0 = w.state()[14];
    let pivot = screwdriver::pivot();
    for _ in 0..3 {
        let tips = w.tip_centers();
        let moves: Vec<_> = w
            .scene()
            .task_fingers()
            .iter()
            .map(|f| {
                let p: Point3<f64> = tips[f.index()];
                let radial = Vector3::new(p.x - pivot.x, p.y - pivot.y, 0.0).normalize();
                (*f, (-Vector3::z()).cross(&radial) * 0.006)
            })
            .collect();
        let dq = scripted::tip_moves_to_action(&w, &moves);
        w.step_action(&dq).unwrap();
    }
    w.state()[14] - y0
}
fn card_graze(opt: &dyn Fn(&mut WorldParams), gap: f64) -> f64 {
    let mut w = world(SceneKind::Card, opt);
    back_off(&mut w, gap);
    let y0 = w.state()[9];
    for _ in 0..4 {
        let dq = scripted::card_push_action(&w, -0.008, 0.0);
        w.step_action(&dq).unwrap();
    }
    w.state()[9] - y0
}
fn card_slide(opt: &dyn Fn(&mut WorldParams), press: f64) -> f64 {
    let mut w = world(SceneKind::Card, opt);
    let y0 = w.state()[9];
    for _ in 0..4 {
        let dq = scripted::card_push_action(&w, -0.008, press);
        w.step_action(&dq).unwrap();
    }
    w.state()[9] - y0
}
fn index_cap(opt: &dyn Fn(&mut WorldParams)) -> f64 {
    let mut w = world(SceneKind::Screwdriver, opt);
    for _ in 0..3 {
        let dq =
            scripted::tip_moves_to_action(&w, &[(Finger::Index, Vector3::new(0.004, 0.0, 0.0003))]);
        w.step_action(&dq).unwrap();
    }
    let s = w.state();
    s[12].abs().max(s[13].abs())
}
fn pinch(opt: &dyn Fn(&mut WorldParams), subs: usize) -> (f64, f64) {
    let mut w = world(SceneKind::Screwdriver, &|p| {
        opt(p);
        p.substeps = subs;
    });
    let y0 = w.state()[14];
    let t = std::time::Instant::now();
    for _ in 0..4 {
        let dq = scripted::pinch_turn_action(&w, 0.004, 0.006);
        w.step_action(&dq).unwrap();
    }
    (w.state()[14] - y0, t.elapsed().as_secs_f64() * 250.0)
}

#[test]
#[ignore = "a measurement that prints docs/world.md's options table"]
fn options() {
    let opts: Vec<Variant> = vec![
        (
            "plain cone, step",
            Box::new(|p: &mut WorldParams| {
                p.cone_activation = ConeActivation::All;
                p.command_profile = CommandProfile::Step;
            }),
        ),
        (
            "plain cone, ramp",
            Box::new(|p: &mut WorldParams| {
                p.cone_activation = ConeActivation::All;
            }),
        ),
        (
            "pressing cone, step",
            Box::new(|p: &mut WorldParams| {
                p.command_profile = CommandProfile::Step;
            }),
        ),
        ("pressing cone, ramp", Box::new(|_p: &mut WorldParams| {})),
        (
            "staggered, step",
            Box::new(|p: &mut WorldParams| {
                p.friction_model = FrictionModel::Staggered;
                p.command_profile = CommandProfile::Step;
            }),
        ),
        (
            "staggered, ramp",
            Box::new(|p: &mut WorldParams| {
                p.friction_model = FrictionModel::Staggered;
            }),
        ),
    ];
    println!(
        "| option (screwdriver; card runs use the same cone/profile with its own friction model) | graze 1/2/5/10 mm Δyaw | index 0.3 mm over cap tilt | pinch-and-turn Δyaw 5/10/20 sub-steps | ms/action (10) |"
    );
    for (name, o) in &opts {
        let g: Vec<String> = [0.001, 0.002, 0.005, 0.01]
            .iter()
            .map(|g| format!("{:.3}", graze(o.as_ref(), *g)))
            .collect();
        let ic = index_cap(o.as_ref());
        let p: Vec<(f64, f64)> = [5, 10, 20].iter().map(|s| pinch(o.as_ref(), *s)).collect();
        println!(
            "| {name} | {} | {ic:.4} | {:.3} / {:.3} / {:.3} | {:.2} |",
            g.join(" / "),
            p[0].0,
            p[1].0,
            p[2].0,
            p[1].1
        );
    }
    let copts: Vec<Variant> = vec![
        (
            "anitescu plain, step",
            Box::new(|p: &mut WorldParams| {
                p.friction_model = FrictionModel::Anitescu;
                p.cone_activation = ConeActivation::All;
                p.command_profile = CommandProfile::Step;
            }),
        ),
        (
            "anitescu pressing, ramp",
            Box::new(|p: &mut WorldParams| {
                p.friction_model = FrictionModel::Anitescu;
            }),
        ),
        (
            "staggered, step",
            Box::new(|p: &mut WorldParams| {
                p.command_profile = CommandProfile::Step;
            }),
        ),
        ("staggered, ramp", Box::new(|_p: &mut WorldParams| {})),
    ];
    println!(
        "| card option | graze 1/2/5 mm Δy (mm) | 0.5 mm over, from contact, Δy (mm) | press 3 mm push Δy (cm), 5/10/20 sub-steps |"
    );
    for (name, o) in &copts {
        let g: Vec<String> = [0.001, 0.002, 0.005]
            .iter()
            .map(|g| format!("{:.3}", 1e3 * card_graze(o.as_ref(), *g)))
            .collect();
        let free = card_slide(o.as_ref(), -0.0005) * 1e3;
        let pr: Vec<String> = [5, 10, 20]
            .iter()
            .map(|s| {
                format!(
                    "{:.3}",
                    1e2 * card_slide(
                        &|p: &mut WorldParams| {
                            o(p);
                            p.substeps = *s;
                        },
                        0.003
                    )
                )
            })
            .collect();
        println!(
            "| {name} | {} | {free:.3} | {} |",
            g.join(" / "),
            pr.join(" / ")
        );
    }
}
