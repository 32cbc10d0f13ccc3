//! Camera intrinsics from a ROS `camera_info` YAML file: what `camera_calibration` writes and the
//! ROS Kinect drivers read (`~/.ros/camera_info/rgb_<serial>.yaml`, `depth_<serial>.yaml`):
//!
//! ```yaml
//! image_width: 640
//! image_height: 480
//! camera_name: rgb_A00362A09353042A
//! camera_matrix: {rows: 3, cols: 3, data: [525, 0, 319.5, 0, 525, 239.5, 0, 0, 1]}
//! distortion_model: plumb_bob
//! distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}
//! ```
//!
//! Only the camera matrix is used (frames are published unrectified, with pinhole intrinsics);
//! a calibration made at another resolution than 640x480 is scaled to it. Distortion and the
//! rectification and projection matrices are read and reported, not applied.

use std::path::{Path, PathBuf};

use crate::{HEIGHT, Pinhole, WIDTH};

/// Why a calibration file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The file cannot be read.
    #[error("cannot read the camera calibration {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a camera_info YAML document.
    #[error("{path} is not a ROS camera_info YAML file: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the line where the YAML parser knows it.
        reason: String,
    },
}

#[derive(Debug, serde::Deserialize)]
struct Matrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

#[derive(Debug, serde::Deserialize)]
struct CameraInfoYaml {
    image_width: u32,
    image_height: u32,
    #[serde(default)]
    camera_name: String,
    camera_matrix: Matrix,
    #[serde(default)]
    distortion_model: String,
    #[serde(default)]
    distortion_coefficients: Option<Matrix>,
}

/// A calibration read from a camera_info file, scaled to 640x480.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    /// `camera_name` of the file (often the device serial).
    pub camera_name: String,
    /// Intrinsics at 640x480.
    pub intrinsics: Pinhole,
    /// The size the calibration was made at.
    pub calibrated_size: (u32, u32),
    /// `distortion_model` and its coefficients, as read (not applied).
    pub distortion: (String, Vec<f64>),
}

impl CameraInfo {
    /// Reads and checks a camera_info YAML file.
    pub fn from_file(path: &Path) -> Result<CameraInfo, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|source| CalibrationError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        CameraInfo::parse(&text).map_err(|reason| CalibrationError::Format {
            path: path.to_path_buf(),
            reason,
        })
    }

    /// Parses the text of a camera_info YAML file.
    pub fn parse(text: &str) -> Result<CameraInfo, String> {
        let y: CameraInfoYaml = serde_yaml::from_str(text).map_err(|e| e.to_string())?;
        let k = &y.camera_matrix;
        if k.rows != 3 || k.cols != 3 || k.data.len() != 9 {
            return Err(format!(
                "camera_matrix must be 3x3 with 9 values (rows {}, cols {}, {} values)",
                k.rows,
                k.cols,
                k.data.len()
            ));
        }
        if y.image_width == 0 || y.image_height == 0 {
            return Err(format!(
                "image size {}x{} is empty",
                y.image_width, y.image_height
            ));
        }
        let (sx, sy) = (
            WIDTH as f64 / f64::from(y.image_width),
            HEIGHT as f64 / f64::from(y.image_height),
        );
        if (sx - sy).abs() > 1e-9 {
            return Err(format!(
                "image size {}x{} is not 4:3 like the camera's 640x480",
                y.image_width, y.image_height
            ));
        }
        let d = &k.data;
        if d[1] != 0.0 || d[3] != 0.0 || d[6] != 0.0 || d[7] != 0.0 || d[8] != 1.0 {
            return Err(format!(
                "camera_matrix {d:?} is not of the form [fx 0 cx; 0 fy cy; 0 0 1]"
            ));
        }
        // Pixel centres: (u + 0.5) scales, so c' = (c + 0.5) * s - 0.5.
        let intrinsics = Pinhole {
            fx: d[0] * sx,
            fy: d[4] * sy,
            cx: (d[2] + 0.5) * sx - 0.5,
            cy: (d[5] + 0.5) * sy - 0.5,
        };
        if !intrinsics.is_valid() {
            return Err(format!(
                "camera_matrix gives unusable intrinsics {intrinsics:?}"
            ));
        }
        Ok(CameraInfo {
            camera_name: y.camera_name,
            intrinsics,
            calibrated_size: (y.image_width, y.image_height),
            distortion: (
                y.distortion_model,
                y.distortion_coefficients
                    .map(|m| m.data)
                    .unwrap_or_default(),
            ),
        })
    }

    /// True when the file declares a distortion that is not negligible (the frames are published
    /// unrectified; a caller warns).
    pub fn has_distortion(&self) -> bool {
        self.distortion.1.iter().any(|c| c.abs() > 1e-3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROS_FILE: &str = "image_width: 640
image_height: 480
camera_name: rgb_A00362A09353042A
camera_matrix:
  rows: 3
  cols: 3
  data: [521.3, 0, 312.7,
         0, 520.9, 249.1, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.18, -0.32, 0.001, -0.002, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [521.3, 0, 312.7, 0, 0, 520.9, 249.1, 0, 0, 0, 1, 0]
";

    #[test]
    fn reads_a_ros_camera_info_file() {
        let c = CameraInfo::parse(ROS_FILE).unwrap();
        assert_eq!(c.camera_name, "rgb_A00362A09353042A");
        assert_eq!(
            c.intrinsics,
            Pinhole {
                fx: 521.3,
                fy: 520.9,
                cx: 312.7,
                cy: 249.1
            }
        );
        assert_eq!(c.distortion.0, "plumb_bob");
        assert!(c.has_distortion());
    }

    #[test]
    fn scales_a_calibration_made_at_another_resolution() {
        let text = ROS_FILE
            .replace("image_width: 640", "image_width: 1280")
            .replace("image_height: 480", "image_height: 960");
        let c = CameraInfo::parse(&text).unwrap();
        assert!((c.intrinsics.fx - 260.65).abs() < 1e-9);
        assert!((c.intrinsics.cx - ((312.7 + 0.5) / 2.0 - 0.5)).abs() < 1e-9);
        assert_eq!(c.calibrated_size, (1280, 960));
    }

    #[test]
    fn malformed_files_say_what_is_wrong() {
        let e = CameraInfo::parse("image_width: 640\n").unwrap_err();
        assert!(e.contains("missing field"), "{e}");
        let e = CameraInfo::parse(&ROS_FILE.replace("data: [521.3, 0, 312.7,", "data: [521.3,"))
            .unwrap_err();
        assert!(e.contains("9 values"), "{e}");
        let e = CameraInfo::parse(&ROS_FILE.replace("image_height: 480", "image_height: 400"))
            .unwrap_err();
        assert!(e.contains("4:3"), "{e}");
        let e =
            CameraInfo::parse(&ROS_FILE.replace("521.3, 0, 312.7", "-1, 0, 312.7")).unwrap_err();
        assert!(e.contains("unusable"), "{e}");
        let e = CameraInfo::parse("camera_matrix: [").unwrap_err();
        assert!(e.contains("line"), "{e}");
        let dir = std::env::temp_dir().join("robocog-no-such-calibration.yaml");
        let e = CameraInfo::from_file(&dir).unwrap_err().to_string();
        assert!(e.contains("cannot read the camera calibration"), "{e}");
    }
}
