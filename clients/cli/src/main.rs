//! relief: the command-line client of reliefd.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::{Parser, Subcommand};
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use tokio_stream::StreamExt;

mod connect;
mod output;

#[derive(Parser)]
#[command(name = "relief", version, about = "Talk to a running reliefd")]
struct Args {
    /// reliefd's gRPC address: http://HOST:PORT, or https://HOST:PORT for TLS.
    #[arg(long, global = true, default_value = "http://127.0.0.1:50051", env = "RELIEF_SERVER")]
    server: String,
    /// Bearer token sent with every call, for a reliefd serving with
    /// --token-file (RELIEF_TOKEN keeps it out of the process list).
    #[arg(long, global = true, env = "RELIEF_TOKEN", hide_env_values = true, value_name = "TOKEN")]
    token: Option<String>,
    /// CA certificate (PEM) that signed an https:// server's certificate
    /// (else RELIEF_CA; else the system's CA bundle).
    #[arg(long, global = true, value_name = "PEM")]
    ca: Option<PathBuf>,
    /// Print JSON for scripts instead of text.
    #[arg(long, global = true)]
    json: bool,
    /// Send the token over plain http:// to another machine anyway
    /// (anyone on the path can read it there).
    #[arg(long, global = true)]
    insecure: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The scene: sources and their status, generation, effects, counters.
    State,
    /// Follow scene events (new generations, source errors) as they happen.
    Watch {
        /// Only events after this generation.
        #[arg(long, default_value_t = 0)]
        from: u64,
    },
    /// Wait until the scene reaches a generation.
    Wait {
        generation: u64,
        #[arg(long, default_value_t = 30.0)]
        timeout: f64,
    },
    /// Fetch one tile: heights as a GeoTIFF, colour as a PNG, features as GeoJSON.
    Tile {
        source: String,
        level: u32,
        x: u32,
        y: u32,
        #[arg(short, long)]
        output: PathBuf,
        /// Resampling kernel for this request (nearest, bilinear, cubic, lanczos).
        #[arg(long)]
        resampling: Option<String>,
    },
    /// Elevations at points given as LON,LAT (degrees); null where there is no data.
    Elevation {
        #[arg(required = true, value_name = "LON,LAT")]
        points: Vec<String>,
        /// Height source; the scene's height layer by default.
        #[arg(long)]
        source: Option<String>,
    },
    /// Re-read source files now (all, or the named sources).
    Reload { sources: Vec<String> },
    /// Set a parameter as if the manifest said so (checked as the manifest is;
    /// a new generation dirties what it touches): a source's option, or a
    /// knob of "[quality]", "[sun]" or "[effects.NAME]". The value is TOML
    /// (270, true, [0.8, 1.2]); other text is a string (#ff0000, cubic).
    Set {
        /// A source id, "[quality]", "[sun]" or "[effects.NAME]".
        target: String,
        /// The option or knob.
        key: String,
        /// Its value; left out with --reset.
        #[arg(required_unless_present = "reset")]
        value: Option<String>,
        /// Put the manifest's value back.
        #[arg(long, conflicts_with = "value")]
        reset: bool,
    },
    /// Render a view as a PNG.
    Render {
        /// LON,LAT,ALT,HEADING,PITCH,ROLL (degrees and metres); the current camera when left out.
        #[arg(long, value_name = "LON,LAT,ALT,HEADING,PITCH,ROLL", allow_hyphen_values = true)]
        camera: Option<String>,
        /// Vertical field of view in degrees (with --camera; default 50).
        #[arg(long)]
        fov: Option<f64>,
        /// Image size.
        #[arg(long, default_value = "1280x720", value_name = "WxH")]
        size: String,
        #[arg(short, long)]
        output: PathBuf,
        /// Clipmap samples per level side (63, 127, 255, ...), for this frame only.
        #[arg(long)]
        grid_size: Option<u32>,
        /// Clipmap levels, for this frame only.
        #[arg(long)]
        levels: Option<u32>,
        /// The sun at this date-time, with its UTC offset (2026-06-21T15:00:00+02:00), over the camera.
        #[arg(long, conflicts_with_all = ["sun_azimuth", "sun_elevation"])]
        sun_time: Option<String>,
        /// A fixed sun: azimuth, degrees clockwise from north (with --sun-elevation).
        #[arg(long, requires = "sun_elevation", allow_hyphen_values = true)]
        sun_azimuth: Option<f64>,
        /// A fixed sun: elevation, degrees above the horizon (with --sun-azimuth).
        #[arg(long, requires = "sun_azimuth", allow_hyphen_values = true)]
        sun_elevation: Option<f64>,
    },
    /// The current camera.
    #[command(subcommand)]
    Camera(CameraCommand),
}

#[derive(Subcommand)]
enum CameraCommand {
    /// Print the current camera.
    Get,
    /// Set the current camera.
    Set {
        #[arg(value_name = "LON,LAT,ALT,HEADING,PITCH,ROLL", allow_hyphen_values = true)]
        camera: String,
        /// Vertical field of view in degrees; kept as it is when left out.
        #[arg(long)]
        fov: Option<f64>,
    },
}

/// Six comma-separated numbers as a camera.
fn parse_camera(text: &str, fov: f64) -> anyhow::Result<pb::Camera> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().with_context(|| format!("'{v}' in '{text}' is not a number")))
        .collect::<anyhow::Result<_>>()?;
    let [lon_deg, lat_deg, altitude_m, heading_deg, pitch_deg, roll_deg] = values[..] else {
        bail!("'{text}' is not LON,LAT,ALT,HEADING,PITCH,ROLL (six numbers)");
    };
    Ok(pb::Camera { lon_deg, lat_deg, altitude_m, heading_deg, pitch_deg, roll_deg, vertical_fov_deg: fov })
}

fn parse_size(text: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = text.split_once(['x', 'X']).with_context(|| format!("'{text}' is not WxH"))?;
    Ok((
        w.trim().parse().with_context(|| format!("'{w}' is not a width"))?,
        h.trim().parse().with_context(|| format!("'{h}' is not a height"))?,
    ))
}

fn main() -> ExitCode {
    let args = Args::parse();
    let runtime = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("relief: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(run(args)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("relief: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Turns a gRPC status into a plain error with its message.
fn rpc<T>(sent: connect::Sent, result: Result<tonic::Response<T>, tonic::Status>) -> anyhow::Result<T> {
    result.map(tonic::Response::into_inner).map_err(|s| connect::status_error(&s, sent))
}

fn parse_point(text: &str) -> anyhow::Result<pb::GeodeticPoint> {
    let Some((lon, lat)) = text.split_once(',') else {
        bail!("'{text}' is not LON,LAT");
    };
    let lon_deg: f64 = lon.trim().parse().with_context(|| format!("'{lon}' is not a longitude"))?;
    let lat_deg: f64 = lat.trim().parse().with_context(|| format!("'{lat}' is not a latitude"))?;
    Ok(pb::GeodeticPoint { lon_deg, lat_deg })
}

async fn run(args: Args) -> anyhow::Result<()> {
    let bearer = connect::Bearer::new(args.token.as_deref())?;
    let options = connect::Options {
        server: &args.server,
        ca: args.ca.as_deref(),
        ca_env: std::env::var_os(connect::CA_ENV).filter(|v| !v.is_empty()).map(PathBuf::from),
    };
    options.check_token_path(bearer.is_set(), args.insecure)?;
    let channel = connect::channel(&options).await?;
    let sent = connect::Sent { token: bearer.is_set(), tls: options.is_tls() };
    let mut scene = SceneServiceClient::with_interceptor(channel.clone(), bearer.clone());
    let mut views = ViewServiceClient::with_interceptor(channel.clone(), bearer.clone())
        .max_decoding_message_size(256 * 1024 * 1024);
    let mut tiles = TileServiceClient::with_interceptor(channel, bearer).max_decoding_message_size(256 * 1024 * 1024);
    match args.command {
        Command::State => {
            let state = rpc(sent, scene.get_state(pb::GetStateRequest {}).await)?;
            output::emit(args.json, &output::state_json(&state), || output::state_text(&state));
        }
        Command::Watch { from } => {
            let mut stream = rpc(sent, scene.watch(pb::WatchRequest { from_generation: from }).await)?;
            while let Some(event) = stream.next().await {
                let event = event.map_err(|s| connect::status_error(&s, sent))?;
                output::emit(args.json, &output::event_json(&event), || output::event_text(&event));
            }
        }
        Command::Wait { generation, timeout } => {
            if !(timeout.is_finite() && timeout >= 0.0) {
                bail!("--timeout {timeout} is not a number of seconds");
            }
            let state = rpc(
                sent,
                scene
                    .wait_for_generation(pb::WaitForGenerationRequest {
                        min_generation: generation,
                        timeout_ms: (timeout * 1000.0).min(f64::from(u32::MAX)) as u32,
                    })
                    .await,
            )?;
            output::emit(args.json, &output::state_json(&state), || format!("generation {}", state.generation));
        }
        Command::Tile { source, level, x, y, output: path, resampling } => {
            let tile = rpc(
                sent,
                tiles
                    .get_tile(pb::GetTileRequest {
                        source_id: source,
                        key: Some(pb::TileKey { level, x, y }),
                        quality: Some(pb::QualityOverrides { resampling, ..Default::default() }),
                    })
                    .await,
            )?;
            write_tile(&tile, &path)?;
            output::emit(args.json, &output::tile_json(&tile, &path), || {
                format!(
                    "wrote {}x{} tile {level}/{x}/{y} of '{}' (generation {}, hash {:016x}) to {}",
                    tile.width,
                    tile.height,
                    tile.source_id,
                    tile.generation,
                    tile.content_hash,
                    path.display()
                )
            });
        }
        Command::Elevation { points, source } => {
            let points = points.iter().map(|p| parse_point(p)).collect::<anyhow::Result<Vec<_>>>()?;
            let answer = rpc(
                sent,
                tiles
                    .sample_elevation(pb::SampleElevationRequest {
                        points: points.clone(),
                        source_id: source.unwrap_or_default(),
                    })
                    .await,
            )?;
            output::emit(args.json, &output::proto_json(&answer), || {
                points
                    .iter()
                    .zip(&answer.samples)
                    .map(|(p, s)| match s.height_m {
                        Some(h) => format!("{:.6},{:.6}\t{h:.3}", p.lon_deg, p.lat_deg),
                        None => format!("{:.6},{:.6}\tnull", p.lon_deg, p.lat_deg),
                    })
                    .collect::<Vec<_>>()
                    .join("\n")
            });
        }
        Command::Render { camera, fov, size, output, grid_size, levels, sun_time, sun_azimuth, sun_elevation } => {
            let (width, height) = parse_size(&size)?;
            let camera = camera.map(|c| parse_camera(&c, fov.unwrap_or(50.0))).transpose()?;
            let quality = (grid_size.is_some() || levels.is_some()).then(|| pb::QualityOverrides {
                clipmap_grid_size: grid_size,
                clipmap_levels: levels,
                ..Default::default()
            });
            let sun = (sun_time.is_some() || sun_azimuth.is_some()).then(|| pb::Sun {
                time: sun_time.unwrap_or_default(),
                azimuth_deg: sun_azimuth,
                elevation_deg: sun_elevation,
            });
            let format = pb::ImageFormat::Png as i32;
            let frame =
                rpc(sent, views.render(pb::RenderRequest { camera, width, height, format, quality, sun }).await)?;
            std::fs::write(&output, &frame.image).with_context(|| format!("cannot write {}", output.display()))?;
            let value = output::frame_json(&frame, &output);
            output::emit(args.json, &value, || output::frame_text(&frame, &output));
        }
        Command::Camera(CameraCommand::Get) => {
            let camera = rpc(sent, views.get_camera(pb::GetCameraRequest {}).await)?;
            output::emit(args.json, &output::camera_json(&camera), || output::camera_text(&camera));
        }
        Command::Camera(CameraCommand::Set { camera, fov }) => {
            let current = rpc(sent, views.get_camera(pb::GetCameraRequest {}).await)?;
            let camera = parse_camera(&camera, fov.unwrap_or(current.vertical_fov_deg))?;
            let set = rpc(sent, views.set_camera(pb::SetCameraRequest { camera: Some(camera) }).await)?;
            output::emit(args.json, &output::camera_json(&set), || output::camera_text(&set));
        }
        Command::Reload { sources } => {
            let state = rpc(sent, scene.reload(pb::ReloadRequest { source_ids: sources }).await)?;
            output::emit(args.json, &output::state_json(&state), || output::state_text(&state));
        }
        Command::Set { target, key, value, reset } => {
            let request =
                pb::SetSourceParameterRequest { source_id: target, name: key, value: value.unwrap_or_default(), reset };
            let state = rpc(sent, scene.set_source_parameter(request).await)?;
            output::emit(args.json, &output::state_json(&state), || output::parameters_text(&state));
        }
    }
    Ok(())
}

/// Heights become a single-band Float32 GeoTIFF whose pixel centres are the
/// tile's corner-aligned samples; colour is written as the PNG it came as.
fn write_tile(tile: &pb::GetTileResponse, path: &Path) -> anyhow::Result<()> {
    match &tile.payload {
        Some(pb::get_tile_response::Payload::ColorPng(png)) => {
            std::fs::write(path, png).with_context(|| format!("cannot write {}", path.display()))
        }
        Some(pb::get_tile_response::Payload::HeightsF32Le(bytes)) => {
            let (w, h) = (tile.width as usize, tile.height as usize);
            if bytes.len() != w * h * 4 || w < 2 || h < 2 {
                bail!("reliefd sent {} bytes for a {w}x{h} height tile", bytes.len());
            }
            let heights: Vec<f32> =
                bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
            let e = tile.extent.context("reliefd sent a tile without an extent")?;
            let (step_x, step_y) = ((e.max_x - e.min_x) / (w - 1) as f64, (e.max_y - e.min_y) / (h - 1) as f64);
            let driver = gdal::DriverManager::get_driver_by_name("GTiff").context("GDAL has no GTiff driver")?;
            let mut ds = driver
                .create_with_band_type::<f32, _>(path, w, h, 1)
                .with_context(|| format!("cannot create {}", path.display()))?;
            ds.set_geo_transform(&[e.min_x - step_x / 2.0, step_x, 0.0, e.max_y + step_y / 2.0, 0.0, -step_y])?;
            let srs = gdal::spatial_ref::SpatialRef::from_definition(&tile.crs)
                .with_context(|| format!("reliefd sent an unknown CRS '{}'", tile.crs))?;
            ds.set_spatial_ref(&srs)?;
            let mut band = ds.rasterband(1)?;
            band.set_no_data_value(Some(f64::NAN))?;
            let mut buffer = gdal::raster::Buffer::new((w, h), heights);
            band.write((0, 0), (w, h), &mut buffer)?;
            Ok(())
        }
        Some(pb::get_tile_response::Payload::FeaturesGeojson(json)) => {
            std::fs::write(path, json).with_context(|| format!("cannot write {}", path.display()))
        }
        Some(pb::get_tile_response::Payload::Mesh(mesh)) => write_obj(tile, mesh, path),
        Some(pb::get_tile_response::Payload::Instances(list)) => {
            let text = output::instances_geojson(list).to_string();
            std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
        }
        Some(pb::get_tile_response::Payload::MaskU8(_)) => {
            bail!("mask tiles cannot be written yet")
        }
        None => bail!("reliefd sent a tile without a payload"),
    }
}

/// A mesh tile as Wavefront OBJ in metres east, north and up of the
/// tile's south-west corner at height 0 (on a geodetic grid, exact through
/// ECEF), one object per feature: any 3D tool opens it.
fn write_obj(tile: &pb::GetTileResponse, mesh: &pb::Mesh, path: &Path) -> anyhow::Result<()> {
    let values: Vec<f64> =
        mesh.positions_f64_le.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or_default())).collect();
    let indices: Vec<u32> =
        mesh.indices_u32_le.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap_or_default())).collect();
    if !values.len().is_multiple_of(3) || indices.iter().any(|&i| i as usize >= values.len() / 3) {
        bail!("reliefd sent a mesh whose indices do not match its {} positions", values.len() / 3);
    }
    let e = tile.extent.context("reliefd sent a tile without an extent")?;
    let geodetic = tile.crs == "EPSG:4326";
    let mut out = format!(
        "# relief mesh tile {}/{}/{} of '{}', generation {}\n# metres east, north, up of ({}, {}) in {}{}\n",
        tile.key.map_or(0, |k| k.level),
        tile.key.map_or(0, |k| k.x),
        tile.key.map_or(0, |k| k.y),
        tile.source_id,
        tile.generation,
        e.min_x,
        e.min_y,
        tile.crs,
        if geodetic { " (local tangent frame)" } else { "" }
    );
    for p in values.chunks_exact(3) {
        let v = if geodetic {
            relief_source::geodesy::enu_from_geodetic([e.min_x, e.min_y, 0.0], [p[0], p[1], p[2]])
        } else {
            [p[0] - e.min_x, p[1] - e.min_y, p[2]]
        };
        let _ = writeln!(out, "v {:.4} {:.4} {:.4}", v[0], v[1], v[2]);
    }
    for part in &mesh.parts {
        let _ = writeln!(out, "o feature_{}", part.feature_id);
        let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
        for t in indices.get(range).unwrap_or_default().chunks_exact(3) {
            let _ = writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
    }
    std::fs::write(path, out).with_context(|| format!("cannot write {}", path.display()))
}
