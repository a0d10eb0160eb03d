//! `--meshes N,…`: how load and render time grow with a mesh's triangle
//! count. Measures the seed room, the bunny room (the seed room with the
//! Stanford bunny in place of its boxes, as `scenes/bunny.json`, when
//! `scenes/models/bunny.obj` is found from the current folder) and the same
//! room with a generated bumpy torus of N triangles in place of the bunny
//! (same silhouette at every N), each at the same settings.

use std::path::Path;
use std::time::{Duration, Instant};

use super::{BenchArgs, CliError, build, median, render_once, scenes};
use crate::render::generate_mesh::{TORUS_HALF_HEIGHT, write_torus_obj};
use crate::render::scene_file::{MeshDesc, MeshScale, MeshShading, ObjectDesc, SceneDesc};

/// The torus is scaled to the bunny's width (about 4).
const TORUS_SCALE: f64 = 1.4;

/// The room with `mesh` in place of the boxes (where the bunny stands).
fn room_with(base: &SceneDesc, mesh: MeshDesc) -> SceneDesc {
    let mut d = base.clone();
    d.objects.retain(|o| !matches!(o, ObjectDesc::Box(_)));
    d.objects.push(ObjectDesc::Mesh(mesh));
    d
}

fn mesh_desc(file: &Path, scale: f64, translate: [f64; 3], rotate: f64) -> MeshDesc {
    MeshDesc {
        file: file.to_string_lossy().into_owned(),
        material: "sand".into(),
        scale: MeshScale::Uniform(scale),
        rotate_y_deg: rotate,
        translate,
        shading: MeshShading::Smooth,
    }
}

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let Some(counts) = &args.meshes else {
        return Err(CliError::input(
            "--meshes needs counts, e.g. --meshes 10000,1000000",
        ));
    };
    let runs = args.runs.unwrap_or(if args.quick { 1 } else { 5 });
    let base = scenes(&BenchArgs {
        scene: None,
        spheres: None,
        ..args.clone()
    })?
    .remove(0)
    .desc;
    let dir = tempfile::tempdir().map_err(CliError::other)?;
    let mut rooms: Vec<(String, SceneDesc, usize)> = vec![("seed room".into(), base.clone(), 0)];
    let bunny = std::env::current_dir()
        .map_err(CliError::other)?
        .join("scenes/models/bunny.obj");
    if bunny.exists() {
        let m = mesh_desc(&bunny, 0.4, [0.0, 0.0013, 0.5], 180.0);
        rooms.push(("bunny room".into(), room_with(&base, m), 3_674));
    } else {
        outln!("(no scenes/models/bunny.obj here: the bunny room is left out)");
    }
    for &n in counts {
        let file = dir.path().join(format!("torus-{n}.obj"));
        let exact = write_torus_obj(&file, n as usize).map_err(CliError::other)?;
        let lift = TORUS_HALF_HEIGHT * TORUS_SCALE + 0.0013;
        let m = mesh_desc(&file, TORUS_SCALE, [0.0, lift, 0.5], 0.0);
        rooms.push((format!("torus {exact}"), room_with(&base, m), exact));
    }
    let r = &base.render;
    outln!(
        "{}×{}, {} {} shadow rays, depth {}; medians of {runs} rounds, each rendering every room in turn; ratios are the median of the rounds' own (load: reading the files and building the scene)",
        base.camera.width,
        base.camera.height,
        r.shadow_rays,
        r.sampling.name(),
        r.max_depth
    );
    outln!(
        "{:<16} {:>10} {:>10} {:>11} {:>12}",
        "scene",
        "triangles",
        "load ms",
        "render ms",
        "vs seed room"
    );
    // Every room is built before any is timed, and the timed renders go
    // round the rooms in turn: a change in the machine's speed (other work
    // on it) then falls on all rooms alike, and each ratio is the median
    // of the rounds' own ratios, not of medians taken minutes apart.
    let mut built = Vec::with_capacity(rooms.len());
    for (_, desc, _) in &rooms {
        let mut loads: Vec<Duration> = Vec::new();
        let mut loaded = None;
        for _ in 0..runs.max(1) {
            drop(loaded.take());
            let start = Instant::now();
            loaded = Some(build(desc, true)?);
            loads.push(start.elapsed());
        }
        loads.sort();
        built.push((loaded.expect("built at least once"), median(&loads)));
    }
    let mut rounds: Vec<Vec<f64>> = Vec::new();
    for _ in 0..runs.max(1) {
        let round = built
            .iter()
            .map(|(loaded, _)| render_once(loaded).elapsed.as_secs_f64())
            .collect();
        rounds.push(round);
    }
    let median_over_rounds = |of: &dyn Fn(&[f64]) -> f64| -> f64 {
        let mut values: Vec<f64> = rounds.iter().map(|r| of(r)).collect();
        values.sort_by(f64::total_cmp);
        let n = values.len();
        if n % 2 == 1 {
            values[n / 2]
        } else {
            0.5 * (values[n / 2 - 1] + values[n / 2])
        }
    };
    let mut torus_rooms: Vec<(usize, usize)> = Vec::new();
    for (room, ((name, _, triangles), (_, load))) in rooms.iter().zip(&built).enumerate() {
        if name.starts_with("torus") {
            torus_rooms.push((room, *triangles));
        }
        outln!(
            "{:<16} {:>10} {:>10.1} {:>11.1} {:>11.2}×",
            name,
            triangles,
            load.as_secs_f64() * 1e3,
            median_over_rounds(&|r| r[room]) * 1e3,
            median_over_rounds(&|r| r[room] / r[0])
        );
    }
    if let (Some(&(first, fewest)), Some(&(last, most))) = (torus_rooms.first(), torus_rooms.last())
        && torus_rooms.len() > 1
    {
        outln!(
            "render time from {fewest} to {most} triangles: {:.2}×",
            median_over_rounds(&|r| r[last] / r[first])
        );
    }
    Ok(())
}
