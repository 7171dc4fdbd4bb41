//! `previz sun` end to end: the published case, JSON, batch CSV, photos, bad input, the chart.

use std::process::{Command, Output};

const EXE: &str = env!("CARGO_BIN_EXE_previz");
const PVLIB_TABLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/sun/pvlib_spa_reference.csv");
const PHOTOS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/photos/exif_gps");

fn sun(args: &[&str]) -> Output {
    Command::new(EXE).arg("sun").args(args).output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).unwrap()
}

const GOLDEN: [&str; 14] = [
    "--lat",
    "39.742476",
    "--lon",
    "-105.1786",
    "--time",
    "2003-10-17T12:30:30-07:00",
    "--elevation",
    "1830.14",
    "--pressure",
    "820",
    "--temperature",
    "11",
    "--delta-t",
    "67",
];

#[test]
fn published_case_as_text_and_json() {
    let o = sun(&GOLDEN);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    // NREL/TP-560-34302 Table A5.1.
    assert!(text.contains("apparent zenith   50.111622°"), "{text}");
    assert!(text.contains("azimuth           194.340241°"), "{text}");
    assert!(text.contains("sunrise           2003-10-17 06:12:43"), "{text}");
    assert!(text.contains("equation of time  14.64 min"), "{text}");

    let mut args = GOLDEN.to_vec();
    args.extend(["--json", "--slope", "30", "--surface-azimuth", "170"]);
    let o = sun(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!((v["apparent_zenith_deg"].as_f64().unwrap() - 50.111_62).abs() < 5e-6);
    assert!((v["azimuth_deg"].as_f64().unwrap() - 194.340_24).abs() < 5e-6);
    assert!((v["incidence_deg"].as_f64().unwrap() - 25.187).abs() < 5e-6);
    assert_eq!(v["day"]["kind"], "rises_and_sets");
    let d: Vec<f64> = v["direction_enu"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!((d.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-6);
    assert!(d[2] > 0.0 && d[1] < 0.0); // up and to the south
}

#[test]
fn polar_night_is_said_plainly() {
    let o = sun(&["--lat", "78.22", "--lon", "15.65", "--time", "2024-12-21T12:00:00+01:00", "--algorithm", "grena5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("none: polar night"), "{text}");
    assert!(text.contains("sunlight factor   0.0000"), "{text}");
    assert!(text.contains("algorithm         grena5"), "{text}");
}

#[test]
fn bad_input_fails_cleanly_naming_the_flag() {
    let cases: [(&[&str], &str); 9] = [
        (&["--lat", "91", "--lon", "0", "--time", "2020-01-01T00:00:00Z"], "--lat"),
        (&["--lat", "NaN", "--lon", "0", "--time", "2020-01-01T00:00:00Z"], "--lat"),
        (&["--lat", "0", "--lon", "-180.5", "--time", "2020-01-01T00:00:00Z"], "--lon"),
        (&["--lat", "0", "--lon", "0", "--time", "yesterday"], "--time"),
        (&["--lat", "0", "--lon", "0", "--time", "2021-02-29T00:00:00Z"], "--time"),
        (&["--lat", "0", "--lon", "0", "--time", "+6001-01-01T00:00:00Z"], "--time"),
        (&["--lat", "0", "--lon", "0", "--time", "2000-01-01T00:00:00Z", "--algorithm", "psa2020"], "--time"),
        (&["--lat", "0", "--lon", "0", "--time", "2000-01-01T00:00:00Z", "--algorithm", "sun-dial"], "--algorithm"),
        (&["--lat", "abc", "--lon", "0", "--time", "2000-01-01T00:00:00Z"], "--lat"),
    ];
    for (args, flag) in cases {
        let o = sun(args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(stdout(&o).is_empty(), "{args:?}");
    }
}

#[test]
fn batch_reproduces_pvlib_and_reports_bad_rows() {
    // The reference table has the batch layout plus pvlib's results as extra columns.
    let o = sun(&["--batch", PVLIB_TABLE]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut r = csv::Reader::from_reader(o.stdout.as_slice());
    let h = r.headers().unwrap().clone();
    let idx = |n: &str| h.iter().position(|x| x == n).unwrap();
    assert_eq!(h.len(), 11 + 4);
    let rows: Vec<_> = r.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 483);
    for row in &rows {
        assert_eq!(&row[idx("error")], "");
        for (ours, theirs) in
            [("zenith_deg", "pvlib_zenith_deg"), ("apparent_zenith_deg", "pvlib_apparent_zenith_deg"), ("azimuth_deg", "pvlib_azimuth_deg")]
        {
            let a: f64 = row[idx(ours)].parse().unwrap();
            let b: f64 = row[idx(theirs)].parse().unwrap();
            let d = (a - b).abs();
            assert!(d.min(360.0 - d) <= 1e-4, "{row:?}");
        }
    }

    let dir = std::env::temp_dir().join(format!("previz-sun-batch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cases.csv");
    std::fs::write(
        &path,
        "id,utc,lat,lon,elevation_m,pressure_mbar,temperature_c,delta_t_s\n\
         a,2003-10-17T19:30:30Z,39.742476,-105.1786,1830.14,820,11,67\n\
         b,2003-10-17T19:30:30Z,95,0,,,,\n\
         c,not-a-time,0,0,,,,\n\
         d,2024-06-21T12:00:00Z,0,0,,,,\n\
         e,2024-06-21T12:00:00Z,0,east,,,,\n\
         f,7000-01-01T00:00:00Z,0,0,,,,\n",
    )
    .unwrap();
    let o = sun(&["--batch", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut r = csv::Reader::from_reader(o.stdout.as_slice());
    let rows: Vec<_> = r.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 6);
    let error = |i: usize| rows[i][11].to_string();
    assert!((rows[0][9].parse::<f64>().unwrap() - 50.111_62).abs() < 5e-6);
    assert_eq!(error(0), "");
    assert!(error(1).starts_with("lat:"), "{}", error(1));
    assert!(error(2).starts_with("utc:"), "{}", error(2));
    assert_eq!(error(3), "");
    assert!(error(4).starts_with("lon:"), "{}", error(4));
    assert!(error(5).contains("7000"), "{}", error(5));
    assert_eq!(&rows[1][0], "b"); // extra columns copied through
    assert!(rows[1][8].is_empty());
    assert!(stderr(&o).contains("4 of 6 rows had errors"));
    std::fs::remove_dir_all(&dir).unwrap();

    let o = sun(&["--batch", "/nonexistent/cases.csv"]);
    assert!(!o.status.success() && stderr(&o).contains("--batch"));
}

#[test]
fn from_photo_uses_gps_time_and_warns_about_the_camera_clock() {
    let photo = format!("{PHOTOS}/arezzo_0010.jpg");
    // The table's weather and ΔT (pvlib's defaults), so only the algorithms differ.
    let weather = ["--pressure", "1013.25", "--temperature", "12", "--delta-t", "67", "--elevation", "0"];
    let mut args = vec!["--from-photo", &photo, "--json"];
    args.extend(weather);
    let o = sun(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["time_utc"], "2008-10-23T14:27:07.240Z");
    assert!(v["source"].as_str().unwrap().contains("GPS"));
    // exif_gps_metadata.csv (pvlib, printed to 3 decimals): elevation 17.063°, azimuth 234.454°.
    assert!((v["apparent_elevation_deg"].as_f64().unwrap() - 17.063).abs() < 0.001);
    assert!((v["azimuth_deg"].as_f64().unwrap() - 234.454).abs() < 0.001);
    assert!(stderr(&o).contains("differ by -21.97 h"), "{}", stderr(&o));

    // No GPS time, no offset: an error naming the way out; with an offset it works.
    let florence = format!("{PHOTOS}/87_OSError.jpg");
    let o = sun(&["--from-photo", &florence]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--photo-utc-offset"), "{}", stderr(&o));
    let o = sun(&["--from-photo", &florence, "--photo-utc-offset", "+01:00", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["time_utc"], "2005-12-14T13:39:47Z");
    assert!((v["elevation_m"].as_f64().unwrap() - 42.12).abs() < 0.01); // GPS altitude
    let mut args = vec!["--from-photo", &florence, "--photo-utc-offset", "+01:00", "--json"];
    args.extend(weather);
    let v: serde_json::Value = serde_json::from_str(&stdout(&sun(&args))).unwrap();
    assert!((v["apparent_elevation_deg"].as_f64().unwrap() - 14.736).abs() < 0.001);
    assert!((v["azimuth_deg"].as_f64().unwrap() - 215.316).abs() < 0.001);

    let o = sun(&["--from-photo", "/nonexistent.jpg"]);
    assert!(!o.status.success() && stderr(&o).contains("--from-photo"));
}

#[test]
fn chart_and_bench_run_small() {
    let dir = std::env::temp_dir().join(format!("previz-sun-chart-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("chart.png");
    let csv_path = dir.join("chart.csv");
    let o = sun(&["chart", "--cases", "200", "-o", png.to_str().unwrap(), "--csv", csv_path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (1400, 900));
    let text = std::fs::read_to_string(&csv_path).unwrap();
    assert_eq!(text.lines().count(), 1 + 10);
    assert!(text.lines().any(|l| l.starts_with("spa,-2000,6000,200,")));
    std::fs::remove_dir_all(&dir).unwrap();

    let o = sun(&["bench", "--cases", "100", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["algorithm"], "spa");
    assert!(v["evals_per_s"].as_f64().unwrap() > 0.0);
}
