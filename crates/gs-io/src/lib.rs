//! # gs-io
//!
//! File formats of vagsl: COLMAP sparse models (text and binary, read and write, every
//! non-fisheye camera model), transforms.json scenes, undistortion to PINHOLE and
//! downscaling, scene loading, the Inria 3DGS Gaussian PLY, mesh PLY and OBJ, and float EXR
//! maps. Every reader returns a clear [`IoError`] naming the file and the problem; every
//! writer is atomic (temporary file + rename).
//!
//! ## COLMAP models and scenes
//!
//! Read a sparse model (text or binary, detected), write it in the other format, and load a
//! scene folder as undistorted PINHOLE views:
//!
//! ```no_run
//! use gs_io::colmap::{read_model, write_binary};
//! use gs_io::scene::{load_scene, model_summary, LoadOptions, Resolution};
//! use std::path::Path;
//!
//! let model = read_model(Path::new("scene/sparse/0"))?;
//! println!("{} images, {} points", model.images.len(), model.points3d.len());
//! write_binary(&model, Path::new("scene/sparse_bin"))?;
//!
//! println!("{}", model_summary(Path::new("scene"))?); // counts, cameras, reprojection error
//! let scene = load_scene(Path::new("scene"), &LoadOptions {
//!     resolution: Resolution::Factor(2), // -r 2 (default: downscale only images wider than 1600 px)
//!     ..Default::default()
//! })?;
//! let view = &scene.views[0]; // sorted by name, PINHOLE, image [H][W][3] f32 in [0, 1]
//! assert_eq!(view.image.width() as u32, view.camera.width);
//! # Ok::<(), gs_io::IoError>(())
//! ```
//!
//! A scene folder may instead hold a nerfstudio / instant-ngp `transforms.json` (or Blender's
//! `transforms_train.json` + `transforms_test.json`): [`load_scene`] detects the layout
//! ([`layout`]; COLMAP wins when both exist) and [`transforms`] reads it into the same COLMAP
//! model types, converting the OpenGL camera→world poses to COLMAP's world→camera.
//!
//! Camera models with distortion project and undistort points like COLMAP:
//!
//! ```
//! use gs_io::colmap::{CameraModel, ColmapCamera};
//! use gs_io::undistort::{undistort_camera, UndistortOptions};
//!
//! let cam = ColmapCamera { id: 1, model: CameraModel::OpenCv, width: 540, height: 960,
//!     params: vec![687.76, 687.245, 277.279, 482.634, 0.0578421, -0.0805099, -0.000980296, 0.00015575] };
//! let distorted = cam.img_from_cam([0.3, -0.6]);
//! let ray = cam.cam_from_img(distorted).unwrap();
//! assert!((ray[0] - 0.3).abs() < 1e-12 && (ray[1] + 0.6).abs() < 1e-12);
//! // The PINHOLE camera `colmap image_undistorter` would produce (no blank pixels).
//! let pinhole = undistort_camera(&cam, &UndistortOptions::default()).unwrap();
//! assert_eq!((pinhole.model, pinhole.width, pinhole.height), (CameraModel::Pinhole, 533, 948));
//! ```

pub mod atomic;
pub mod capped;
pub mod colmap;
pub mod depth_dir;
pub mod error;
pub mod exr;
pub mod integrity;
pub mod json;
pub mod layout;
pub mod npy;
pub mod obj;
pub mod output;
pub mod photo;
pub mod ply;
pub mod png;
pub mod scene;
pub mod transforms;
pub mod undistort;

pub use atomic::{remove_stale_temps, write_atomic};
pub use capped::{JSON_CAP, SETTINGS_CAP, read_capped};
pub use colmap::{ColmapModel, read_model};
pub use depth_dir::{depth_candidates, read_view_depth};
pub use layout::{SceneLayout, SceneModel, detect_layout};
pub use scene::{LoadOptions, MaskPolicy, Resolution, load_scene, mask_path, model_summary, read_scene_model};
pub use error::{IoError, Result};
pub use self::exr::{read_exr, write_depth_exr, write_exr, write_normal_exr};
pub use npy::{NpyArray, read_npy, read_npy_array, read_npz, write_npy};
pub use obj::read_obj;
pub use json::json_error_words;
pub use output::{check_output_path, check_output_writable};
pub use png::{write_jpeg, write_png};
pub use ply::gaussian::{parse_gaussian_ply, read_gaussian_ply, write_gaussian_ply};
pub use ply::mesh::{parse_mesh_ply, read_mesh_ply, write_mesh_ply};
