//! The command line: arguments are parsed by clap, each subcommand is one function, and
//! [`main`] maps every error to an exit code in one place.
//!
//! A subcommand's arguments as typed are a `*Cli` struct here (or a module's own clap
//! struct, as `render_cmd::RenderArgs`); its function turns them into what the module takes.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use crate::error::Error;
use crate::recover::{self as recover_cmd, Effort};
use crate::{bench, compare, downsample, render_cmd};

#[derive(Parser)]
#[command(
    name = "relume",
    version,
    about = "Recover the materials of a scene from one panorama, and re-render it"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render every view of a scene with the given materials (one EXR and one PNG per view).
    Render(render_cmd::RenderArgs),
    /// Recover every group's material from the panorama (the views' images).
    Recover(RecoverCli),
    /// Check a scene and its panorama as `recover` does before its work, with a first look at its light.
    ///
    /// Each group's pure pixels per view, the lights the views see against their declared
    /// radiance, each view's orientation, and a first diffuse colour per group at a few
    /// samples (whether light reaches it, and whether a view reads far off the others
    /// under it); nothing written but --json.
    Check(CheckCli),
    /// Equirectangular panoramas: a 360-degree capture split into a scene's views, or a
    /// scene's rendered views joined into one.
    #[command(subcommand)]
    Panorama(PanoramaCommand),
    /// Compare two sets of views, or two materials files.
    #[command(subcommand)]
    Compare(CompareCommand),
    /// Benchmarks that print figures.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(clap::Args)]
struct RecoverCli {
    /// The scene.toml, whose views carry the panorama's images.
    scene: PathBuf,
    /// Output folder: materials.toml, materials.rad, report.json, views/, errors/.
    #[arg(long)]
    out: PathBuf,
    /// Random seed: the same seed gives the same materials.toml bytes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// How much work to spend (samples per evaluation and in the final render).
    #[arg(long, value_enum, default_value_t = Effort::Default)]
    effort: Effort,
    #[command(flatten)]
    knobs: BudgetOverrides,
}

#[derive(clap::Args)]
struct CheckCli {
    /// The scene.toml, whose views carry the panorama's images.
    scene: PathBuf,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Also write the findings as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Subcommand)]
enum PanoramaCommand {
    /// Split an equirectangular image into the six cube faces a scene's views are.
    ///
    /// Writes <out>/views/<face>.exr, and <out>/views.toml with their [[view]] tables. The
    /// image's centre column looks along --forward, its columns turn to the right, its top
    /// row looks along --up.
    Split(SplitCli),
    /// Join a scene's views, rendered from one position, into one equirectangular EXR.
    ///
    /// The views are `relume render`'s <view>.exr in a folder; the result is an
    /// environment map of a relit or edited scene for other tools.
    Join(JoinCli),
}

#[derive(clap::Args)]
struct SplitCli {
    /// The equirectangular image (.exr, .hdr or .png), twice as wide as high.
    image: PathBuf,
    /// Where the panorama was taken, in the scene's coordinates: X,Y,Z (default: where
    /// the --scene's views all are).
    #[arg(long, value_parser = parse_position, allow_hyphen_values = true)]
    position: Option<[f64; 3]>,
    #[command(flatten)]
    frame: PanoramaFrame,
    /// Pixels per face side (default: the image's width / 16, four texels a pixel).
    #[arg(long)]
    size: Option<u32>,
    /// A scene.toml whose geometry, lights and groups go with the faces into
    /// <out>/scene.toml (its own views left out), ready for check and recover.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(clap::Args)]
struct JoinCli {
    /// The scene.toml whose views the images are.
    scene: PathBuf,
    /// The folder of <view>.exr.
    dir: PathBuf,
    /// The equirectangular EXR to write (<name>.exr; a tone-mapped <name>.png beside it).
    #[arg(long)]
    out: PathBuf,
    /// Its width in texels, twice its height (default: four times the widest view's side,
    /// about a texel per view pixel on the horizon).
    #[arg(long)]
    width: Option<u32>,
    #[command(flatten)]
    frame: PanoramaFrame,
    /// Worker threads (default: all cores); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

/// How an equirectangular image lies in the scene.
#[derive(clap::Args)]
struct PanoramaFrame {
    /// The scene direction at the image's centre column: X,Y,Z (Blender's world images:
    /// -1,0,0).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "1,0,0")]
    forward: [f32; 3],
    /// The scene's up, towards the image's top edge: X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "0,0,1")]
    up: [f32; 3],
}

/// Overrides of single knobs of the `--effort` level (for studying the time/accuracy trade).
#[derive(clap::Args)]
struct BudgetOverrides {
    /// Samples per pixel of the renders inside the loops.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    loop_spp: Option<u32>,
    /// Samples per pixel of a lobe's transport cache; the cache holds at least 4096
    /// pixels' worth of them (2^16 samples at the least), however few its pixels.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    cache_spp: Option<u32>,
    /// Temperature levels of the stage-2 annealing (10 proposals each).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    anneal_levels: Option<u32>,
    /// Samples per pixel of the final render.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    final_spp: Option<u32>,
    /// The search that refines stage 2's proposal.
    #[arg(long, value_enum)]
    optimiser: Option<recover_cmd::Optimiser>,
    /// Keep at most N pure pixels of a group, as GROUP=N (stability studies).
    #[arg(long, value_parser = parse_group_limit)]
    limit_group_pixels: Option<(String, u32)>,
}

impl BudgetOverrides {
    fn apply(&self, effort: Effort) -> recover_cmd::Budget {
        let mut b = effort.budget();
        b.loop_spp = self.loop_spp.unwrap_or(b.loop_spp);
        b.cache_spp = self.cache_spp.unwrap_or(b.cache_spp);
        b.anneal_levels = self.anneal_levels.unwrap_or(b.anneal_levels);
        b.final_spp = self.final_spp.unwrap_or(b.final_spp);
        b.optimiser = self.optimiser.unwrap_or(b.optimiser);
        b
    }
}

/// "X,Y,Z" as three finite numbers.
fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    parse_position(s).map(|v| v.map(|x| x as f32))
}

/// X,Y,Z kept in 64 bits, as a scene file's view positions are, within 32-bit floats'
/// range, in which views are made (a --position of 1e39 was refused after the capture was
/// read, as a capacity of the core).
fn parse_position(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let numbers: Vec<f64> = parts
        .iter()
        .filter_map(|p| p.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect();
    match numbers[..] {
        [x, y, z] if parts.len() == 3 => match numbers.iter().all(|&v| (v as f32).is_finite()) {
            true => Ok([x, y, z]),
            false => Err(format!("'{s}' is out of range for 32-bit floats")),
        },
        _ => Err(format!("expected three finite numbers X,Y,Z, got '{s}'")),
    }
}

fn parse_group_limit(s: &str) -> Result<(String, u32), String> {
    let (group, n) = s
        .split_once('=')
        .ok_or_else(|| format!("expected GROUP=N, got '{s}'"))?;
    let n = n
        .parse::<u32>()
        .map_err(|e| format!("'{n}' is not a pixel count: {e}"))?;
    Ok((group.to_string(), n))
}

#[derive(Subcommand)]
enum CompareCommand {
    /// Per group and per view: relative difference of mean radiance and relative RMS, over
    /// the pixels whose whole footprint sees one group.
    Views(CompareViewsCli),
    /// Class per group and parameter errors of a materials file against the truth.
    Materials(CompareMaterialsCli),
    /// Whether a recovery's reported standard errors (report.json) cover the truth as
    /// often as they claim, over the groups recovered in their true class (several
    /// reports, e.g. of several seeds, are pooled).
    Uncertainty(CompareUncertaintyCli),
}

#[derive(clap::Args)]
struct CompareViewsCli {
    /// The scene.toml whose views the images are (it decides each pixel's group).
    scene: PathBuf,
    /// Folder of `<view>.exr` files: the reference (A).
    dir_a: PathBuf,
    /// Folder of `<view>.exr` files: compared against A.
    dir_b: PathBuf,
    /// Folder of an independent render of B's materials (another seed): adds each
    /// row's misfit, its relative RMS with the render noise taken out
    /// (sqrt(mean (B - A).(B2 - A)) / mean A; negative where it is under the noise), and
    /// its mean bias, the difference of the means with the noise taken out.
    #[arg(long, value_name = "DIR_B2")]
    independent: Option<PathBuf>,
    /// Compare only these views (by name), as `render --view` renders them: the
    /// folders need no image of the others.
    #[arg(long = "view")]
    views: Vec<String>,
    /// Also write the table as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Worker threads (default: all cores); the figures do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(clap::Args)]
struct CompareMaterialsCli {
    /// The true materials (truth.toml, or any materials file taken as the reference).
    truth: PathBuf,
    /// The materials compared with it (a recovery's materials.toml).
    materials: PathBuf,
    /// The truth's scene.toml: its kinds judge the kinds of the recovered lobes (a
    /// recovery of kind "auto" groups writes the kind it chose).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Also write the table as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct CompareUncertaintyCli {
    /// The true materials (truth.toml).
    truth: PathBuf,
    /// One or more report.json (several seeds of the scene are pooled).
    #[arg(required = true, num_args = 1..)]
    report: Vec<PathBuf>,
    /// Also write the coverage as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Trace a ray file (shared/bench/rays format): Mrays/s on 1 thread and on all threads.
    Rays(BenchRaysCli),
    /// Box-average a scene's panorama by an integer factor into a new scene (for timing
    /// and judging recovery at several resolutions).
    Downsample(DownsampleCli),
    /// Recovery's accuracy against wall time, one knob at a time (effort, annealing
    /// length, samples per evaluation, view resolution, Nelder-Mead against annealing):
    /// tradeoff.csv, tradeoff.svg (and the same chart as tradeoff.png) and a table.
    Tradeoff(bench::tradeoff::TradeoffArgs),
    /// Recovery under perturbations (seeds, image noise, exposure, light radiance, view
    /// size, pixels of one group): stability.csv, seed-spread.csv, stability.svg (and .png)
    /// and a verdict on the targets.
    Stability(bench::stability::StabilityArgs),
    /// Edited scenes (other lights, a new viewpoint, objects removed or added) rendered
    /// from recovered materials and from the true ones, each against the edit's reference
    /// images: edits.csv, edits.json and a table. Each is rendered again on the next seed,
    /// so that the errors are also given with the render noise taken out. Materials for
    /// added objects come from a materials.toml beside the edit's scene.toml.
    Edits(bench::edits::EditsArgs),
}

#[derive(clap::Args)]
struct BenchRaysCli {
    /// The scene.toml whose geometry the rays are traced against.
    scene: PathBuf,
    /// The ray file: a count, then origins and unit directions (shared/bench/rays/README.md).
    #[arg(long)]
    rays: PathBuf,
    /// Write the closest hits in the reference format.
    #[arg(long)]
    hits: Option<PathBuf>,
    /// Write the figures as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Reference hits to check against (default: the .hits beside the .rays).
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Threads of the second timing (default: all cores); the first is on one.
    #[arg(long)]
    threads: Option<usize>,
    /// Timed runs (best is kept) after one warm-up.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    repeats: u32,
}

#[derive(clap::Args)]
struct DownsampleCli {
    /// The scene.toml whose views are box-averaged.
    scene: PathBuf,
    #[arg(long)]
    factor: u32,
    #[arg(long)]
    out: PathBuf,
}

/// `relume check`'s findings: a table of each group's pure pixels per view, the lights'
/// readings, each view's orientation, then the warnings.
fn print_check(report: &recover_cmd::CheckReport) {
    let widths: Vec<usize> = report.views.iter().map(|v| v.len().max(6)).collect();
    let mut header = format!("{:<16} {:<8} {:>11}", "group", "kind", "pure pixels");
    for (v, w) in report.views.iter().zip(&widths) {
        header.push_str(&format!(" {v:>w$}"));
    }
    println!("{header}  first diffuse colour");
    for g in &report.groups {
        let mut row = format!("{:<16} {:<8} {:>11}", g.group, g.kind, g.total());
        for (n, w) in g.pure_pixels.iter().zip(&widths) {
            row.push_str(&format!(" {n:>w$}"));
        }
        match g.preview_colour {
            Some([r, gr, b]) => row.push_str(&format!("  {r:.3} {gr:.3} {b:.3}")),
            None => row.push_str("  -"),
        }
        println!("{row}");
    }
    println!(
        "first diffuse colour: stage 1's iteration at {} samples per pixel ({}), every group diffuse: a reading of the scene's light and the panorama's scale, not a result (a glossy group's is off)",
        report.preview_spp,
        crate::text::counted(report.preview_renders, "render")
    );
    if report.light_readings.is_empty() {
        println!("{}", crate::recover::CALIBRATION_NOT_CHECKED);
    }
    for r in &report.light_readings {
        println!("calibration: {}", r.describe());
    }
    for view in &report.views {
        match report.orientation_readings.iter().find(|r| &r.view == view) {
            Some(r) => println!("orientation: {}", r.describe()),
            None => println!(
                "orientation: view '{view}' not read (too few boundaries between groups in its pure pixels)"
            ),
        }
    }
    if !report.few_pixels.is_empty() {
        let groups: Vec<String> = report
            .few_pixels
            .iter()
            .map(|(g, n)| format!("{g} {n}"))
            .collect();
        println!(
            "few pixels: {} (fewer than {} pure pixels): a lobe recovered there was seen to change with the seed (docs/stability.md); a finer panorama sees them better",
            groups.join(", "),
            crate::recover::FEW_PIXELS
        );
    }
    for (group, why) in &report.unfit_for_a_map {
        println!(
            "texture coordinates: group '{group}': {why}: a texture it shows is told, and it keeps a uniform model"
        );
    }
    for (group, span) in &report.tiled {
        println!(
            "tiles: group '{group}': texture coordinates {span}, past [0, 1]: a texture it shows is taken as tiled over it, and its map repeats (diffuse_map_wrap = \"repeat\")"
        );
    }
    for w in &report.warnings {
        eprintln!("relume: warning: {w}");
    }
    println!(
        "checked in {:.1} s: {}",
        report.seconds,
        crate::text::counted(report.warnings.len() as u64, "warning")
    );
}

/// Runs the command line and returns the process exit code.
pub fn main() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    match run(cli.command) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("relume: error: {e}");
            e.exit_code()
        }
    }
}

fn run(command: Command) -> Result<(), Error> {
    match command {
        Command::Render(args) => render(args),
        Command::Recover(args) => recover(args),
        Command::Check(args) => check(args),
        Command::Panorama(PanoramaCommand::Split(args)) => split_panorama(args),
        Command::Panorama(PanoramaCommand::Join(args)) => join_panorama(args),
        Command::Compare(CompareCommand::Views(args)) => compare_views(args),
        Command::Compare(CompareCommand::Materials(args)) => compare_materials(args),
        Command::Compare(CompareCommand::Uncertainty(args)) => compare_uncertainty(args),
        Command::Bench(BenchCommand::Rays(args)) => bench_rays(args),
        Command::Bench(BenchCommand::Downsample(args)) => downsample_scene(args),
        Command::Bench(BenchCommand::Tradeoff(args)) => bench_tradeoff(args),
        Command::Bench(BenchCommand::Stability(args)) => bench_stability(args),
        Command::Bench(BenchCommand::Edits(args)) => bench_edits(args),
    }
}

fn render(args: render_cmd::RenderArgs) -> Result<(), Error> {
    let summary = render_cmd::run(&args)?;
    for w in &summary.warnings {
        eprintln!("relume: warning: {w}");
    }
    println!(
        "rendered {} samples in {:.2} s: {:.3} Msamples/s; wrote {}",
        summary.samples,
        summary.seconds,
        summary.samples as f64 / summary.seconds.max(1e-9) / 1e6,
        args.out.display()
    );
    Ok(())
}

fn recover(cli: RecoverCli) -> Result<(), Error> {
    let RecoverCli {
        scene,
        out,
        seed,
        threads,
        effort,
        knobs,
    } = cli;
    let args = recover_cmd::RecoverArgs {
        scene,
        out,
        seed,
        threads,
        budget: knobs.apply(effort),
        limit_group_pixels: knobs.limit_group_pixels.clone(),
        tell_input_warnings: true,
    };
    let report = recover_cmd::run(&args)?;
    for g in &report.groups {
        println!(
            "{:<16} {:<10} error {:>7}  {}",
            g.group,
            g.model,
            g.error_final
                .map_or("-".into(), |e| format!("{:.2}%", 100.0 * e)),
            g.settling_decision().unwrap_or("")
        );
    }
    match report.light_readings.as_slice() {
        [] => println!("{}", crate::recover::CALIBRATION_NOT_CHECKED),
        readings => {
            for r in readings {
                println!("calibration: {}", r.describe());
            }
        }
    }
    for w in &report.warnings[report.warnings_told..] {
        eprintln!("relume: warning: {w}");
    }
    println!(
        "recovered in {:.1} s; wrote {}",
        report.seconds,
        args.out.display()
    );
    Ok(())
}

fn check(cli: CheckCli) -> Result<(), Error> {
    let CheckCli {
        scene,
        threads,
        json,
    } = cli;
    let report = recover_cmd::check(&scene, threads, json.as_deref())?;
    print_check(&report);
    Ok(())
}

fn split_panorama(cli: SplitCli) -> Result<(), Error> {
    let SplitCli {
        image,
        position,
        frame,
        size,
        scene,
        out,
        threads,
    } = cli;
    let args = crate::panorama::PanoramaArgs {
        image,
        position,
        forward: frame.forward,
        up: frame.up,
        size,
        scene,
        out,
        threads,
        tell_warnings: true,
    };
    let summary = crate::panorama::split(&args)?;
    println!(
        "wrote six {0}x{0} faces ({1}x{1} samples per pixel) and {2}{3} under {4}",
        summary.size,
        summary.samples_per_side,
        crate::panorama::VIEWS_TOML,
        if args.scene.is_some() {
            " and scene.toml"
        } else {
            ""
        },
        args.out.display()
    );
    Ok(())
}

fn join_panorama(cli: JoinCli) -> Result<(), Error> {
    let JoinCli {
        scene,
        dir,
        out,
        width,
        frame,
        threads,
    } = cli;
    let args = crate::panorama::JoinArgs {
        scene,
        dir,
        out,
        width,
        forward: frame.forward,
        up: frame.up,
        threads,
    };
    let joined = crate::panorama::join(&args)?;
    let (width, k) = (joined.width, joined.samples_per_side);
    for w in &joined.warnings {
        eprintln!("relume: warning: {w}");
    }
    println!(
        "wrote {} and its preview {} ({width}x{}, {k}x{k} samples per texel)",
        args.out.display(),
        args.out.with_extension("png").display(),
        width / 2
    );
    Ok(())
}

fn compare_views(cli: CompareViewsCli) -> Result<(), Error> {
    let CompareViewsCli {
        scene,
        dir_a,
        dir_b,
        independent,
        views,
        json,
        threads,
    } = cli;
    compare::compare_views(
        &scene,
        &dir_a,
        &dir_b,
        independent.as_deref(),
        &views,
        json.as_deref(),
        threads,
    )
}

fn compare_materials(cli: CompareMaterialsCli) -> Result<(), Error> {
    let CompareMaterialsCli {
        truth,
        materials,
        scene,
        json,
    } = cli;
    compare::compare_materials(&truth, &materials, scene.as_deref(), json.as_deref())
}

fn compare_uncertainty(cli: CompareUncertaintyCli) -> Result<(), Error> {
    let CompareUncertaintyCli {
        truth,
        report,
        json,
    } = cli;
    compare::check_uncertainty_run(&truth, &report, json.as_deref())?;
    crate::coverage::compare_uncertainty(&truth, &report, json.as_deref())
}

fn bench_rays(cli: BenchRaysCli) -> Result<(), Error> {
    let BenchRaysCli {
        scene,
        rays,
        hits,
        json,
        reference,
        threads,
        repeats,
    } = cli;
    let args = bench::rays::BenchRaysArgs {
        scene,
        rays,
        hits_out: hits,
        json_out: json,
        reference_hits: reference,
        threads,
        repeats: repeats as usize,
    };
    bench::rays::run(&args).map(|_| ())
}

fn downsample_scene(cli: DownsampleCli) -> Result<(), Error> {
    let DownsampleCli { scene, factor, out } = cli;
    for w in downsample::downsample(&scene, factor, &out)? {
        eprintln!("relume: warning: {w}");
    }
    println!("wrote {}", out.join("scene.toml").display());
    Ok(())
}

fn bench_tradeoff(args: bench::tradeoff::TradeoffArgs) -> Result<(), Error> {
    bench::tradeoff::run(&args)?;
    println!(
        "wrote {}, {} and {}",
        args.out.join("tradeoff.csv").display(),
        args.out.join("tradeoff.svg").display(),
        args.out.join("tradeoff.png").display()
    );
    Ok(())
}

fn bench_stability(args: bench::stability::StabilityArgs) -> Result<(), Error> {
    bench::stability::run(&args)?;
    println!(
        "wrote {}, {}, {} and {}",
        args.out.join("stability.csv").display(),
        args.out.join("seed-spread.csv").display(),
        args.out.join("stability.svg").display(),
        args.out.join("stability.png").display()
    );
    Ok(())
}

fn bench_edits(args: bench::edits::EditsArgs) -> Result<(), Error> {
    let outcomes = bench::edits::run(&args)?;
    bench::edits::print_table(&outcomes);
    println!(
        "wrote {} and {}",
        args.out.join("edits.csv").display(),
        args.out.join("edits.json").display()
    );
    Ok(())
}
