//! Writes a simulated stream to a folder: ground truth as TUM, lidar as KITTI `.bin` with
//! `times.txt`, the camera as a TUM RGB-D sequence (`rgbd/`, with `camera.yaml`), 2D scans,
//! IMU, odometry and GNSS (`gnss.csv`) as CSV, and a top view of the world and route.
//! The folder is written under a temporary name and renamed when complete, so a failed run
//! never leaves half-written results.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;

use anyhow::{Context as _, bail};
use sim::Simulation;
use sim::sensors::{LaserScan, Message};

/// Marks a folder as written by `vinebench simulate`, so a rerun may replace it.
const MARKER: &str = ".vinebench-simulate";

#[derive(Debug)]
pub struct Dump {
    target: PathBuf,
    tmp: PathBuf,
    gt: Option<BufWriter<File>>,
    imu: Option<BufWriter<File>>,
    gnss: Option<BufWriter<File>>,
    odom: Option<BufWriter<File>>,
    lidar_times: Option<BufWriter<File>>,
    lidar_count: usize,
    scans: [Option<BufWriter<File>>; 2],
    rgbd_lists: Option<[BufWriter<File>; 3]>,
    /// Encodes and writes the camera's PNGs beside the simulation (started with the first
    /// frame).
    images: Option<ImageWriter>,
    /// The camera's rate, `base_from_optical` and lens, for `rgbd/camera.yaml`.
    camera: (f64, nalgebra::Isometry3<f64>, [f64; 5]),
}

/// One PNG to encode and write: its path, size, colour type and samples (16-bit ones
/// big-endian, as PNG stores them).
type PngJob = (PathBuf, u32, u32, png::ColorType, png::BitDepth, Vec<u8>);

/// A thread that encodes and writes PNGs in the order given, so that the simulation renders
/// the next camera frame meanwhile (encoding a frame's two images took as long as rendering
/// it). Its first error ends it; the next [`ImageWriter::send`] or [`ImageWriter::finish`]
/// returns that error.
#[derive(Debug)]
struct ImageWriter {
    jobs: Option<SyncSender<PngJob>>,
    thread: Option<JoinHandle<anyhow::Result<()>>>,
}

impl ImageWriter {
    /// Frames in flight: enough to even out a slow write, few enough to bound memory
    /// (two 640 x 480 frames are about 3 MB).
    const QUEUE: usize = 4;

    fn start() -> anyhow::Result<Self> {
        let (tx, rx) = sync_channel::<PngJob>(Self::QUEUE);
        let thread = std::thread::Builder::new()
            .name("png-writer".into())
            .spawn(move || {
                for (path, w, h, colour, depth, bytes) in rx {
                    write_png(&path, w, h, colour, depth, &bytes)?;
                }
                Ok(())
            })?;
        Ok(Self {
            jobs: Some(tx),
            thread: Some(thread),
        })
    }

    fn send(&mut self, job: PngJob) -> anyhow::Result<()> {
        if let Some(tx) = &self.jobs
            && tx.send(job).is_ok()
        {
            return Ok(());
        }
        // The thread stopped: its error says why.
        self.finish()?;
        bail!("the PNG writer stopped early")
    }

    /// Waits for every PNG to be written.
    fn finish(&mut self) -> anyhow::Result<()> {
        self.jobs = None;
        match self.thread.take().map(JoinHandle::join) {
            None => bail!("the PNG writer stopped earlier"),
            Some(Ok(result)) => result,
            Some(Err(_)) => bail!("the PNG writer panicked"),
        }
    }
}

impl Drop for ImageWriter {
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn create(path: &Path) -> anyhow::Result<BufWriter<File>> {
    Ok(BufWriter::new(
        File::create(path).with_context(|| path.display().to_string())?,
    ))
}

impl Dump {
    pub fn create(dir: &Path, sim: &Simulation, config: &sim::SimConfig) -> anyhow::Result<Self> {
        if dir.exists() && !dir.join(MARKER).exists() && fs::read_dir(dir)?.next().is_some() {
            bail!(
                "{} exists and was not written by vinebench simulate; choose another --out",
                dir.display()
            );
        }
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "out".into());
        let tmp = dir.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
        if tmp.exists() {
            fs::remove_dir_all(&tmp)?;
        }
        fs::create_dir_all(tmp.join("lidar"))?;
        File::create(tmp.join(MARKER))?;
        crate::topview::draw(sim, &tmp.join("topview.png"))?;
        Ok(Self {
            target: dir.to_owned(),
            tmp,
            gt: None,
            imu: None,
            gnss: None,
            odom: None,
            lidar_times: None,
            lidar_count: 0,
            scans: [None, None],
            rgbd_lists: None,
            images: None,
            camera: (
                config.sensors.camera.rate_hz,
                config.sensors.camera.mount.base_from_sensor() * sim::camera::camera_from_optical(),
                config.sensors.camera.distortion,
            ),
        })
    }

    pub fn write(&mut self, message: &Message) -> anyhow::Result<()> {
        match message {
            Message::GroundTruth(m) => {
                let w = open(&mut self.gt, &self.tmp.join("groundtruth.tum"), None)?;
                let t = m.world_from_base.translation.vector;
                let q = m.world_from_base.rotation.coords; // (i, j, k, w)
                writeln!(
                    w,
                    "{} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
                    seconds(m.stamp_ns),
                    t.x,
                    t.y,
                    t.z,
                    q.x,
                    q.y,
                    q.z,
                    q.w
                )?;
            }
            Message::Imu(m) => {
                let header = "stamp_ns,ax_mps2,ay_mps2,az_mps2,gx_rps,gy_rps,gz_rps";
                let w = open(&mut self.imu, &self.tmp.join("imu.csv"), Some(header))?;
                let (a, g) = (m.accel_mps2, m.gyro_rps);
                writeln!(
                    w,
                    "{},{},{},{},{},{},{}",
                    m.stamp_ns, a.x, a.y, a.z, g.x, g.y, g.z
                )?;
            }
            Message::WheelOdometry(m) => {
                let header = "stamp_ns,linear_mps,angular_rps,x_m,y_m,yaw_rad";
                let w = open(&mut self.odom, &self.tmp.join("odom.csv"), Some(header))?;
                let t = m.odom_from_base.translation.vector;
                let yaw = m.odom_from_base.rotation.euler_angles().2;
                writeln!(
                    w,
                    "{},{},{},{},{},{}",
                    m.stamp_ns, m.linear_mps, m.angular_rps, t.x, t.y, yaw
                )?;
            }
            Message::Lidar(scan) => {
                let times = open(
                    &mut self.lidar_times,
                    &self.tmp.join("lidar/times.txt"),
                    None,
                )?;
                writeln!(times, "{}", seconds(scan.stamp_ns))?;
                // KITTI velodyne format: x, y, z, reflectance in [0, 1], little-endian f32.
                let mut bytes = Vec::with_capacity(scan.points.len() * 16);
                for p in &scan.points {
                    for v in [p.x, p.y, p.z, p.intensity / 255.0] {
                        bytes.extend_from_slice(&v.to_le_bytes());
                    }
                }
                let path = self.tmp.join(format!("lidar/{:06}.bin", self.lidar_count));
                fs::write(&path, bytes).with_context(|| path.display().to_string())?;
                self.lidar_count += 1;
            }
            Message::Rgbd(frame) => self.write_rgbd(frame)?,
            Message::Gnss(m) => {
                // The antenna's fix in the world's east-north-up frame and in WGS-84; an
                // epoch without a fix has empty position fields.
                let header = "stamp_ns,status,satellites,east_m,north_m,up_m,\
                              var_east_m2,var_north_m2,var_up_m2,latitude_deg,longitude_deg,\
                              altitude_m,hdop";
                let w = open(&mut self.gnss, &self.tmp.join("gnss.csv"), Some(header))?;
                let status = m.status.name();
                let p = m
                    .position_enu_m
                    .map_or(",,".to_owned(), |p| format!("{},{},{}", p.x, p.y, p.z));
                let [ve, vn, vu] = m.variance_enu_m2;
                let g = m
                    .geodetic
                    .map_or(",,".to_owned(), |[a, b, c]| format!("{a},{b},{c}"));
                let hdop = m.hdop.map_or(String::new(), |h| h.to_string());
                writeln!(
                    w,
                    "{},{status},{},{p},{ve},{vn},{vu},{g},{hdop}",
                    m.stamp_ns, m.satellites
                )?;
            }
            Message::Scan2d(scan) => {
                let slot = &mut self.scans[scan.side as usize];
                let path = self.tmp.join(format!("{}.csv", scan.side.name()));
                let header = scan_header(scan);
                let w = open(slot, &path, Some(&header))?;
                write!(w, "{}", scan.stamp_ns)?;
                for r in &scan.ranges_m {
                    write!(w, ",{r}")?;
                }
                writeln!(w)?;
            }
        }
        Ok(())
    }

    /// One camera frame in the TUM RGB-D layout (Sturm et al. 2012): `rgbd/rgb/<t>.png`,
    /// `rgbd/depth/<t>.png` (16-bit, metres × 5000, 0 invalid), listed in `rgb.txt` and
    /// `depth.txt`, and paired in `associations.txt` as ORB-SLAM2's and RTAB-Map's tools read;
    /// the first frame also writes `rgbd/camera.yaml`.
    fn write_rgbd(&mut self, frame: &sim::sensors::RgbdFrame) -> anyhow::Result<()> {
        let dir = self.tmp.join("rgbd");
        if self.rgbd_lists.is_none() {
            fs::create_dir_all(dir.join("rgb"))?;
            fs::create_dir_all(dir.join("depth"))?;
            let mut lists = [
                create(&dir.join("rgb.txt"))?,
                create(&dir.join("depth.txt"))?,
                create(&dir.join("associations.txt"))?,
            ];
            writeln!(lists[0], "# color images\n# timestamp filename")?;
            writeln!(
                lists[1],
                "# depth maps (16-bit PNG, depth in metres x 5000, 0: invalid)\n# timestamp filename"
            )?;
            self.rgbd_lists = Some(lists);
            self.images = Some(ImageWriter::start()?);
            write_camera_yaml(&dir.join("camera.yaml"), frame, self.camera)?;
        }
        let t = seconds(frame.stamp_ns);
        let image = &frame.image;
        let (w, h) = (image.width as u32, image.height as u32);
        // Depth in metres x 5000 as 16-bit samples, big-endian as PNG stores them.
        let depth: Vec<u8> = image
            .depth_m
            .iter()
            .flat_map(|&d| {
                let v = if d.is_finite() && d > 0.0 {
                    (d * 5000.0).round().min(65535.0) as u16
                } else {
                    0
                };
                v.to_be_bytes()
            })
            .collect();
        let images = self.images.as_mut().expect("started with the first frame");
        images.send((
            dir.join(format!("rgb/{t}.png")),
            w,
            h,
            png::ColorType::Rgb,
            png::BitDepth::Eight,
            image.rgb.clone(),
        ))?;
        images.send((
            dir.join(format!("depth/{t}.png")),
            w,
            h,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            depth,
        ))?;
        let lists = self.rgbd_lists.as_mut().expect("opened above");
        writeln!(lists[0], "{t} rgb/{t}.png")?;
        writeln!(lists[1], "{t} depth/{t}.png")?;
        writeln!(lists[2], "{t} rgb/{t}.png {t} depth/{t}.png")?;
        Ok(())
    }

    /// Flushes everything and moves the folder into place; returns its path.
    pub fn finish(mut self) -> anyhow::Result<PathBuf> {
        if let Some(images) = self.images.as_mut() {
            images.finish()?;
        }
        let writers = [
            &mut self.gt,
            &mut self.imu,
            &mut self.gnss,
            &mut self.odom,
            &mut self.lidar_times,
        ];
        for w in writers.into_iter().flatten() {
            w.flush()?;
        }
        for w in self
            .scans
            .iter_mut()
            .flatten()
            .chain(self.rgbd_lists.iter_mut().flatten())
        {
            w.flush()?;
        }
        if self.target.exists() {
            fs::remove_dir_all(&self.target).with_context(|| self.target.display().to_string())?;
        }
        fs::rename(&self.tmp, &self.target).with_context(|| self.target.display().to_string())?;
        Ok(self.target.clone())
    }
}

impl Drop for Dump {
    fn drop(&mut self) {
        // Its images first: nothing may still be writing into the folder removed here.
        self.images = None;
        // Only a dump that was not finished still has its temporary folder.
        if self.tmp.exists() {
            let _ = fs::remove_dir_all(&self.tmp);
        }
    }
}

fn open<'a>(
    slot: &'a mut Option<BufWriter<File>>,
    path: &Path,
    header: Option<&str>,
) -> anyhow::Result<&'a mut BufWriter<File>> {
    if slot.is_none() {
        let mut w = create(path)?;
        if let Some(h) = header {
            writeln!(w, "{h}")?;
        }
        *slot = Some(w);
    }
    Ok(slot.as_mut().expect("just opened"))
}

/// `camera.yaml`: the camera's intrinsics in the keys of ORB-SLAM2/3's RGB-D settings files
/// (OpenCV `FileStorage` YAML; the lens's `plumb_bob` coefficients, zero for a rectified
/// image; depth PNGs in metres × 5000), and where it sits on the robot (`groundtruth.tum`
/// is the base's pose, not the camera's).
fn write_camera_yaml(
    path: &Path,
    frame: &sim::sensors::RgbdFrame,
    (rate_hz, base_from_optical, distortion): (f64, nalgebra::Isometry3<f64>, [f64; 5]),
) -> anyhow::Result<()> {
    let [fx, fy, cx, cy] = frame.image.intrinsics;
    let [k1, k2, p1, p2, k3] = distortion;
    let lens = if distortion == [0.0; 5] {
        "pinhole, no distortion"
    } else {
        "a lens's raw image (plumb_bob)"
    };
    let m = base_from_optical.to_homogeneous();
    let rows: Vec<String> = (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:.9}", m[(r, c)]))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    let text = format!(
        "%YAML:1.0\n\
         # The simulated RGB-D camera: {lens}, colour and depth registered (one\n\
         # image plane); depth PNG values are metres x DepthMapFactor, 0 where invalid.\n\
         Camera.type: \"PinHole\"\n\
         Camera.fx: {fx}\nCamera.fy: {fy}\nCamera.cx: {cx}\nCamera.cy: {cy}\n\
         Camera.k1: {k1:?}\nCamera.k2: {k2:?}\nCamera.p1: {p1:?}\nCamera.p2: {p2:?}\nCamera.k3: {k3:?}\n\
         Camera.width: {}\nCamera.height: {}\nCamera.fps: {rate_hz}\nCamera.RGB: 1\n\
         DepthMapFactor: 5000.0\n\
         # base_link from the camera's optical frame (x right, y down, z forward), row-major,\n\
         # metres: groundtruth.tum is base_link's pose in the world.\n\
         base_from_camera: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ {} ]\n",
        frame.image.width,
        frame.image.height,
        rows.join(",\n           ")
    );
    fs::write(path, text).with_context(|| path.display().to_string())
}

fn scan_header(scan: &LaserScan) -> String {
    format!(
        "# angle_min_rad={} angle_increment_rad={} time_increment_s={} range_min_m={} range_max_m={} (inf: no return)\nstamp_ns,ranges_m...",
        scan.angle_min_rad,
        scan.angle_increment_rad,
        scan.time_increment_s,
        scan.range_min_m,
        scan.range_max_m
    )
}

/// A PNG of `bytes` (samples row by row; 16-bit ones big-endian, as PNG stores them),
/// compressed with `png`'s fast mode (fdeflate: the same pixels, files a little larger than
/// its default mode gives, in a fraction of the time).
fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    bytes: &[u8],
) -> anyhow::Result<()> {
    let file = BufWriter::new(File::create(path).with_context(|| path.display().to_string())?);
    let mut encoder = png::Encoder::new(file, width, height);
    encoder.set_color(colour);
    encoder.set_depth(depth);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder
        .write_header()
        .with_context(|| path.display().to_string())?;
    writer
        .write_image_data(bytes)
        .with_context(|| path.display().to_string())?;
    writer
        .finish()
        .with_context(|| path.display().to_string())?;
    Ok(())
}

/// Seconds with nanosecond precision, as TUM files want them.
fn seconds(ns: i64) -> String {
    format!(
        "{}.{:09}",
        ns.div_euclid(1_000_000_000),
        ns.rem_euclid(1_000_000_000)
    )
}

/// Length of the route driven (sampled every 10 ms): the spline's, without the body's
/// vibration, whose millimetre jitter would add to it.
pub fn path_length(sim: &Simulation) -> f64 {
    let step = 10_000_000;
    let mut length = 0.0;
    let mut prev = sim.trajectory.nominal_pose(0).translation.vector;
    let mut t = step;
    while t <= sim.duration_ns() {
        let p = sim.trajectory.nominal_pose(t).translation.vector;
        length += (p - prev).norm();
        prev = p;
        t += step;
    }
    length
}
