//! `previz sun`: the sun's position for a place and time, for a photo, for a CSV of cases, and
//! the accuracy-versus-speed chart of the algorithms. See docs/sun.md.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use chrono::{DateTime, FixedOffset, SecondsFormat, Utc};
use indicatif::{ProgressBar, ProgressStyle};

use crate::sun::{self, Algorithm, Site, SunInput, SunPosition, accuracy, spa};

#[derive(clap::Args, Debug)]
#[command(
    args_conflicts_with_subcommands = true,
    about = "Sun position (NREL SPA by default) for a place and time, a photo's EXIF, or a CSV of cases",
    after_help = "Angles in degrees; azimuth clockwise from true north. Without --pressure/--temperature \
                  the standard atmosphere at --elevation is used; without --delta-t, Espenak & Meeus's ΔT \
                  for the date. Sunrise/transit/sunset are SPA's, for the local day of --time."
)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<SunCommand>,
    /// Latitude in degrees, north positive (−90..90).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub lat: Option<f64>,
    /// Longitude in degrees, east positive (−180..180).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub lon: Option<f64>,
    /// Time in RFC 3339 with an offset or Z, e.g. 2003-10-17T12:30:30-07:00.
    #[arg(long, value_name = "RFC3339", allow_hyphen_values = true)]
    pub time: Option<String>,
    /// Elevation above sea level in metres [default: 0, or the photo's GPS altitude].
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub elevation: Option<f64>,
    /// Air pressure in mbar [default: standard atmosphere at the elevation].
    #[arg(long, value_name = "MBAR", allow_negative_numbers = true)]
    pub pressure: Option<f64>,
    /// Air temperature in °C [default: standard atmosphere at the elevation].
    #[arg(long, value_name = "C", allow_negative_numbers = true)]
    pub temperature: Option<f64>,
    /// ΔT = TT − UT in seconds [default: Espenak & Meeus polynomial for the date].
    #[arg(long = "delta-t", value_name = "S", allow_negative_numbers = true)]
    pub delta_t: Option<f64>,
    /// Position algorithm: spa, grena1..grena5, psa, psa2020, julian.
    #[arg(long, value_name = "NAME", default_value = "spa")]
    pub algorithm: String,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also print the angle of incidence on a surface tilted this much from horizontal (deg).
    #[arg(long, value_name = "DEG", requires = "surface_azimuth", allow_negative_numbers = true)]
    pub slope: Option<f64>,
    /// Azimuth the tilted surface faces, clockwise from north (deg); with --slope.
    #[arg(long, value_name = "DEG", requires = "slope", allow_negative_numbers = true)]
    pub surface_azimuth: Option<f64>,
    /// Read place and time from a photo's EXIF GPS tags (GPS time preferred over the camera clock).
    #[arg(long, value_name = "IMG", conflicts_with_all = ["batch", "lat", "lon"])]
    pub from_photo: Option<PathBuf>,
    /// UTC offset of the photo's camera clock (e.g. +01:00), for photos with no GPS time and no
    /// recorded offset.
    #[arg(long, value_name = "+HH:MM", requires = "from_photo", allow_hyphen_values = true)]
    pub photo_utc_offset: Option<String>,
    /// CSV of cases (header utc,lat,lon,elevation_m,pressure_mbar,temperature_c,delta_t_s;
    /// extra columns copied through); writes the rows with results appended to stdout.
    #[arg(long, value_name = "CASES.csv", conflicts_with_all = ["lat", "lon", "time", "json"])]
    pub batch: Option<PathBuf>,
}

#[derive(clap::Subcommand, Debug)]
pub enum SunCommand {
    /// Chart every algorithm's error against SPA versus its time per evaluation.
    Chart(ChartArgs),
    /// Time one algorithm's evaluations per second on random cases (for comparisons).
    Bench(BenchArgs),
}

#[derive(clap::Args, Debug)]
pub struct ChartArgs {
    /// Output PNG.
    #[arg(short, long, value_name = "PNG", default_value = "sun_accuracy_speed.png")]
    pub output: PathBuf,
    /// Also write the measurements as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Random cases per algorithm.
    #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u32).range(1..))]
    pub cases: u32,
    /// Seed of the random cases.
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Random cases to evaluate (years 1600–3000 for spa, else the algorithm's valid years).
    #[arg(long, default_value_t = 200_000, value_parser = clap::value_parser!(u32).range(1..))]
    pub cases: u32,
    /// Algorithm to time.
    #[arg(long, value_name = "NAME", default_value = "spa")]
    pub algorithm: String,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<()> {
    match args.command {
        Some(SunCommand::Chart(c)) => return chart(&c),
        Some(SunCommand::Bench(b)) => return bench(&b),
        None => {}
    }
    let algorithm = parse_algorithm(&args.algorithm)?;
    if let Some(path) = &args.batch {
        return batch(path, algorithm, &args);
    }
    single(&args, algorithm)
}

fn parse_algorithm(name: &str) -> Result<Algorithm> {
    name.parse().context("--algorithm")
}

/// The instant, its display offset, the site and (for photos) a description of the source.
struct Resolved {
    time: DateTime<FixedOffset>,
    site: Site,
    source: Option<String>,
}

fn resolve(args: &Args) -> Result<Resolved> {
    if let Some(photo) = &args.from_photo {
        let info = sun::exif::PhotoInfo::read(photo)?;
        let given = args.photo_utc_offset.as_deref().map(|o| sun::exif::parse_offset(o).context("--photo-utc-offset")).transpose()?;
        let (time, source) = match &args.time {
            Some(t) => (sun::time::parse_time(t, "--time")?, "--time (overrides the photo)".to_string()),
            None => {
                let (utc, src, warning) = info.instant(given)?;
                if let Some(w) = warning {
                    eprintln!("warning: {}: {w}", photo.display());
                }
                let offset = info.camera_offset.or(given).unwrap_or(FixedOffset::east_opt(0).context("UTC offset")?);
                (utc.with_timezone(&offset), src.describe().to_string())
            }
        };
        let site = Site {
            latitude_deg: info.latitude_deg,
            longitude_deg: info.longitude_deg,
            elevation_m: args.elevation.or(info.altitude_m).unwrap_or(0.0),
        };
        return Ok(Resolved { time, site, source: Some(format!("{} — time from the {source}", photo.display())) });
    }
    let (Some(lat), Some(lon)) = (args.lat, args.lon) else {
        bail!("give --lat and --lon (or --from-photo IMG, or --batch CASES.csv)");
    };
    let Some(time) = &args.time else {
        bail!("--time: missing; give the time in RFC 3339, e.g. 2003-10-17T12:30:30-07:00");
    };
    Ok(Resolved {
        time: sun::time::parse_time(time, "--time")?,
        site: Site { latitude_deg: lat, longitude_deg: lon, elevation_m: args.elevation.unwrap_or(0.0) },
        source: None,
    })
}

fn single(args: &Args, algorithm: Algorithm) -> Result<()> {
    let r = resolve(args)?;
    let input = SunInput {
        time: r.time.with_timezone(&Utc),
        site: r.site,
        pressure_mbar: args.pressure,
        temperature_c: args.temperature,
        delta_t_s: args.delta_t,
    };
    let p = sun::position(&input, algorithm)?;
    let incidence = match (args.slope, args.surface_azimuth) {
        (Some(slope), Some(az)) => {
            // Slope: 0 horizontal, 90 vertical, 180 facing straight down (a negative slope is
            // the same surface with --surface-azimuth turned by 180). Azimuth: NREL SPA's valid
            // input range for the azimuth rotation, −360..=360 (Reda & Andreas 2008, Table A4.1).
            for (v, flag, lo, hi) in [(slope, "--slope", 0.0, 180.0), (az, "--surface-azimuth", -360.0, 360.0)] {
                if !(v.is_finite() && (lo..=hi).contains(&v)) {
                    bail!("{flag} {v}: must be an angle in {lo}..={hi} degrees");
                }
            }
            Some(sun::incidence_deg(p.apparent_zenith_deg, p.azimuth_deg, slope, az))
        }
        _ => None,
    };
    let jd = sun::time::julian_day(&input.time);
    let eot = spa::equation_of_time_min(&spa::geocentric(jd, p.delta_t_s));
    let day = spa::rise_transit_set(
        r.time.date_naive(),
        r.time.offset().local_minus_utc(),
        r.site.latitude_deg,
        r.site.longitude_deg,
        p.delta_t_s,
        spa::DayWindow::LocalDay,
    )?;
    let report = Report { r: &r, p: &p, given: args, incidence, eot, day: &day };
    let text = if args.json { report.json()? } else { report.text() };
    std::io::stdout().lock().write_all(text.as_bytes()).context("writing to stdout")
}

struct Report<'a> {
    r: &'a Resolved,
    p: &'a SunPosition,
    given: &'a Args,
    incidence: Option<f64>,
    eot: f64,
    day: &'a spa::RiseTransitSet,
}

impl Report<'_> {
    fn local(&self, t: Option<DateTime<Utc>>) -> Option<DateTime<FixedOffset>> {
        t.map(|t| t.with_timezone(self.r.time.offset()))
    }

    fn day_kind(&self) -> &'static str {
        match self.day.kind {
            spa::DayKind::RisesAndSets => "rises_and_sets",
            spa::DayKind::PolarDay => "polar_day",
            spa::DayKind::PolarNight => "polar_night",
        }
    }

    fn at_pole(&self) -> bool {
        self.r.site.latitude_deg.abs() == 90.0
    }

    fn text(&self) -> String {
        let (p, r) = (self.p, self.r);
        let how = |given: Option<f64>| if given.is_some() { "given" } else { "default" };
        let d = p.direction_enu();
        let mut s = String::new();
        if let Some(src) = &r.source {
            s += &format!("photo             {src}\n");
        }
        s += &format!(
            "time              {} ({})\n",
            r.time.with_timezone(&Utc).to_rfc3339_opts(SecondsFormat::AutoSi, true),
            r.time.to_rfc3339_opts(SecondsFormat::AutoSi, true)
        );
        s += &format!(
            "place             lat {:.6}°, lon {:.6}°, elevation {} m\n",
            r.site.latitude_deg, r.site.longitude_deg, r.site.elevation_m
        );
        s += &format!(
            "conditions        pressure {:.2} mbar ({}), temperature {:.2} °C ({}), ΔT {:.2} s ({})\n",
            p.pressure_mbar,
            how(self.given.pressure),
            p.temperature_c,
            how(self.given.temperature),
            p.delta_t_s,
            how(self.given.delta_t)
        );
        s += &format!("algorithm         {}\n", p.algorithm);
        s += &format!("zenith            {:.6}° (geometric, no refraction)\n", p.zenith_deg);
        s += &format!("apparent zenith   {:.6}°\n", p.apparent_zenith_deg);
        s += &format!("app. elevation    {:.6}°\n", p.apparent_elevation_deg());
        s += &format!("azimuth           {:.6}° (clockwise from true north)\n", p.azimuth_deg);
        if self.at_pole() {
            s += "                  at a pole every horizontal direction is south (north at the south pole): this azimuth is\n                  measured from the meridian of --lon, the limit along it (docs/sun.md)\n";
        }
        s += &format!("direction (ENU)   [{:.6}, {:.6}, {:.6}]\n", d.x, d.y, d.z);
        s += &format!("sunlight factor   {:.4}\n", p.sunlight_factor());
        if let Some(i) = self.incidence {
            s += &format!("incidence         {i:.6}° on the given surface\n");
        }
        s += &format!("equation of time  {:.2} min (SPA)\n", self.eot);
        let hms = |t: Option<DateTime<FixedOffset>>| t.map_or("-".to_string(), |t| t.format("%Y-%m-%d %H:%M:%S").to_string());
        s += &format!(
            "transit           {}  (sun elevation {:.3}°)\n",
            hms(self.local(Some(self.day.transit))),
            self.day.transit_elevation_deg
        );
        match self.day.kind {
            spa::DayKind::RisesAndSets => {
                s += &format!("sunrise           {}\n", hms(self.local(self.day.sunrise)));
                s += &format!("sunset            {}\n", hms(self.local(self.day.sunset)));
            }
            spa::DayKind::PolarDay => s += "sunrise/sunset    none: polar day, the sun stays above the horizon all day\n",
            spa::DayKind::PolarNight => s += "sunrise/sunset    none: polar night, the sun stays below the horizon all day\n",
        }
        s += &format!("                  (SPA A.2, local day {} at UTC{})\n", r.time.date_naive(), r.time.offset());
        s
    }

    fn json(&self) -> Result<String> {
        let (p, r) = (self.p, self.r);
        let d = p.direction_enu();
        let ts = |t: Option<DateTime<FixedOffset>>| t.map(|t| t.to_rfc3339_opts(SecondsFormat::Millis, true));
        let v = serde_json::json!({
            "time_utc": r.time.with_timezone(&Utc).to_rfc3339_opts(SecondsFormat::AutoSi, true),
            "time_local": r.time.to_rfc3339_opts(SecondsFormat::AutoSi, true),
            "source": r.source,
            "latitude_deg": r.site.latitude_deg,
            "longitude_deg": r.site.longitude_deg,
            "elevation_m": r.site.elevation_m,
            "algorithm": p.algorithm.name(),
            "pressure_mbar": p.pressure_mbar,
            "temperature_c": p.temperature_c,
            "delta_t_s": p.delta_t_s,
            "zenith_deg": p.zenith_deg,
            "apparent_zenith_deg": p.apparent_zenith_deg,
            "apparent_elevation_deg": p.apparent_elevation_deg(),
            "azimuth_deg": p.azimuth_deg,
            "azimuth_at_pole_is_relative_to_meridian": self.at_pole(),
            "direction_enu": [d.x, d.y, d.z],
            "sunlight_factor": p.sunlight_factor(),
            "incidence_deg": self.incidence,
            "equation_of_time_min": self.eot,
            "day": {
                "kind": self.day_kind(),
                "sunrise": ts(self.local(self.day.sunrise)),
                "transit": ts(self.local(Some(self.day.transit))),
                "transit_elevation_deg": self.day.transit_elevation_deg,
                "sunset": ts(self.local(self.day.sunset)),
            },
        });
        Ok(serde_json::to_string_pretty(&v)? + "\n")
    }
}

/// Column names of the batch CSV, and the flag each one stands for in error messages.
const BATCH_COLUMNS: [(&str, &str); 7] = [
    ("utc", "--time"),
    ("lat", "--lat"),
    ("lon", "--lon"),
    ("elevation_m", "--elevation"),
    ("pressure_mbar", "--pressure"),
    ("temperature_c", "--temperature"),
    ("delta_t_s", "--delta-t"),
];

/// Error text of a batch row: the flag names of the single-case checks become column names.
fn batch_message(e: &anyhow::Error) -> String {
    let mut m = format!("{e:#}");
    for (column, flag) in BATCH_COLUMNS {
        if let Some(rest) = m.strip_prefix(flag) {
            m = format!("{column}{rest}");
        }
    }
    m
}

/// Results of one batch row: (zenith, apparent zenith, azimuth).
fn batch_row(fields: &[Option<&str>; 7], algorithm: Algorithm) -> Result<SunPosition> {
    let number = |i: usize| -> Result<Option<f64>> {
        match fields[i].map(str::trim).filter(|s| !s.is_empty()) {
            None => Ok(None),
            Some(s) => s.parse::<f64>().map(Some).with_context(|| format!("{}: cannot read {s:?} as a number", BATCH_COLUMNS[i].0)),
        }
    };
    let utc = fields[0].map(str::trim).filter(|s| !s.is_empty()).context("utc: empty")?;
    let time = sun::time::parse_time(utc, "utc")?.with_timezone(&Utc);
    let (lat, lon) = (number(1)?.context("lat: empty")?, number(2)?.context("lon: empty")?);
    let input = SunInput {
        time,
        site: Site { latitude_deg: lat, longitude_deg: lon, elevation_m: number(3)?.unwrap_or(0.0) },
        pressure_mbar: number(4)?,
        temperature_c: number(5)?,
        delta_t_s: number(6)?,
    };
    sun::position(&input, algorithm)
}

fn batch(path: &Path, algorithm: Algorithm, args: &Args) -> Result<()> {
    let single_only = [args.elevation, args.pressure, args.temperature, args.delta_t, args.slope];
    if args.from_photo.is_some() || single_only.iter().any(Option::is_some) {
        bail!("--batch takes place, weather and ΔT from the CSV columns; only --algorithm applies");
    }
    let mut reader =
        csv::ReaderBuilder::new().flexible(true).from_path(path).with_context(|| format!("--batch: cannot open {}", path.display()))?;
    let header = reader.headers().with_context(|| format!("--batch: cannot read the header of {}", path.display()))?.clone();
    let index: Vec<Option<usize>> = BATCH_COLUMNS.iter().map(|(name, _)| header.iter().position(|h| h.trim() == *name)).collect();
    for (i, (name, _)) in BATCH_COLUMNS.iter().enumerate().take(3) {
        if index[i].is_none() {
            bail!("--batch: {} has no `{name}` column (the header needs at least utc,lat,lon)", path.display());
        }
    }
    let stdout = std::io::stdout();
    let mut writer = csv::Writer::from_writer(stdout.lock());
    let mut out_header = header.clone();
    for extra in ["zenith_deg", "apparent_zenith_deg", "azimuth_deg", "error"] {
        out_header.push_field(extra);
    }
    writer.write_record(&out_header).context("writing to stdout")?;
    let (mut rows, mut failed) = (0usize, 0usize);
    for (line, record) in reader.records().enumerate() {
        rows += 1;
        let mut out: Vec<String>;
        let result = match record {
            Ok(rec) => {
                out = rec.iter().map(str::to_string).collect();
                let fields: [Option<&str>; 7] = std::array::from_fn(|i| index[i].and_then(|j| rec.get(j)));
                if rec.len() != header.len() {
                    Err(anyhow::anyhow!("row has {} fields, the header {}", rec.len(), header.len()))
                } else {
                    batch_row(&fields, algorithm)
                }
            }
            Err(e) => {
                out = Vec::new();
                Err(anyhow::anyhow!("unreadable CSV row {}: {e}", line + 2))
            }
        };
        out.resize(header.len(), String::new());
        match result {
            Ok(p) => out.extend([p.zenith_deg.to_string(), p.apparent_zenith_deg.to_string(), p.azimuth_deg.to_string(), String::new()]),
            Err(e) => {
                failed += 1;
                out.extend([String::new(), String::new(), String::new(), batch_message(&e)]);
            }
        }
        writer.write_record(&out).context("writing to stdout")?;
    }
    writer.flush().context("writing to stdout")?;
    if failed > 0 {
        eprintln!("{failed} of {rows} rows had errors (see the error column)");
    }
    Ok(())
}

fn progress(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg:>18} [{bar:40}] {pos}/{len} ({eta})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}

fn chart(args: &ChartArgs) -> Result<()> {
    let n = args.cases as usize;
    let entries = accuracy::Entry::all();
    let bar = progress((entries.len() * n) as u64, "vs SPA");
    let mut ms = Vec::new();
    for (k, entry) in entries.into_iter().enumerate() {
        bar.set_message(entry.name());
        let mut count = 0u64;
        let m = accuracy::measure(entry, n, args.seed.wrapping_add(k as u64), || {
            count += 1;
            if count.is_multiple_of(1024) {
                bar.inc(1024);
            }
        });
        bar.set_position(((k + 1) * n) as u64);
        ms.push(m);
    }
    bar.finish_and_clear();
    sun::chart::write_png(&ms, &args.output)?;
    let csv = accuracy::to_csv(&ms);
    if let Some(path) = &args.csv {
        crate::output::write_atomic(path, csv.as_bytes())?;
    }
    print!("{csv}");
    eprintln!("wrote {}", args.output.display());
    Ok(())
}

fn bench(args: &BenchArgs) -> Result<()> {
    let algorithm = parse_algorithm(&args.algorithm)?;
    let years = if algorithm == Algorithm::Spa { (1600, 3000) } else { algorithm.valid_years() };
    let cases = accuracy::random_cases(args.cases as usize, years, 1);
    let ns = accuracy::ns_per_eval(accuracy::Entry::Algorithm(algorithm), &cases, 5);
    let per_s = 1e9 / ns;
    if args.json {
        println!("{}", serde_json::json!({"algorithm": algorithm.name(), "cases": cases.len(), "ns_per_eval": ns, "evals_per_s": per_s}));
    } else {
        println!(
            "{algorithm}: {ns:.1} ns per evaluation, {per_s:.0} evaluations/s ({} cases, 5 passes, fastest chunk of {})",
            cases.len(),
            accuracy::TIMING_CHUNK
        );
    }
    Ok(())
}
