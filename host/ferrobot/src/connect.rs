//! Connecting a [`RobotBuilder`]'s backend: the link to the firmware, and the camera device
//! the backend gives (the simulator's renderer, or the camera a simulated world serves beside
//! a serial port), unless the caller gave one. Each backend is a cargo feature.

use crate::backend::device::CameraDevice;
use crate::backend::{Backend, Link};
use crate::builder::{Connected, RobotBuilder};
use crate::config::RobotConfig;
use crate::error::Result;
#[cfg(feature = "serial")]
use std::time::Duration;

/// Connects `b`'s backend for the robot of `cfg` (the host's belief: a calibrated camera
/// mount) whose simulated world, if any, is built from `world_cfg` (the URDF's mount).
pub(crate) fn connect(
    b: RobotBuilder,
    cfg: &RobotConfig,
    world_cfg: RobotConfig,
) -> Result<Connected> {
    #[cfg(feature = "sim")]
    let world = b.world.world()?;
    #[cfg(not(feature = "sim"))]
    let _ = &world_cfg;
    let backend = match b.backend {
        Some(backend) => backend,
        #[cfg(feature = "sim")]
        None => Backend::default(),
        #[cfg(not(feature = "sim"))]
        None => return Err(crate::Error::Usage(
            "no backend chosen: this build of ferrobot has no simulator (cargo feature `sim`); \
                 choose one with RobotBuilder::backend"
                .into(),
        )),
    };
    #[cfg(feature = "sim")]
    if world.shared.is_some() && !matches!(backend, Backend::Sim { .. }) {
        return Err(crate::Error::Usage(format!(
            "a shared world is simulated in-process: it takes the simulator backend, not {backend:?}"
        )));
    }
    let uses_camera = b.uses.camera;
    let camera_device = b.camera_device;
    if let Some(link) = b.link {
        let uses_camera = uses_camera && cfg.camera.is_some();
        return Ok(Connected {
            link,
            camera: camera_device.filter(|_| uses_camera),
            #[cfg(feature = "sim")]
            scene: world.scene,
            #[cfg(feature = "sim")]
            shared: None,
        });
    }
    // The link, and the socket of a camera served from the backend's world, if any.
    let (mut link, served_camera): (Box<dyn Link>, Option<std::path::PathBuf>) = match &backend {
        #[cfg(feature = "sim")]
        Backend::Sim { seed, realtime } => match &world.shared {
            Some((shared, pose)) => (
                Box::new(crate::backend::sim::SimLink::join(
                    &shared.hosts,
                    &world_cfg,
                    *seed,
                    *realtime,
                    *pose,
                )?),
                None,
            ),
            None => (
                Box::new(crate::backend::sim::SimLink::start(
                    &world_cfg,
                    *seed,
                    *realtime,
                    world.scene.clone(),
                )?),
                None,
            ),
        },
        // `ferrobot sim-firmware` serves its world's camera beside the port.
        #[cfg(feature = "serial")]
        Backend::Serial { path } => {
            let socket = crate::backend::camera_socket::socket_beside(path);
            (
                Box::new(crate::backend::serial::SerialLink::open_on(
                    path,
                    Duration::from_secs(10),
                    b.link_time.clone(),
                )?),
                socket.exists().then_some(socket),
            )
        }
        #[cfg(feature = "emulated")]
        Backend::Emulated { .. } | Backend::DirectEmulated => {
            let camera = cfg
                .camera
                .clone()
                .filter(|_| uses_camera && camera_device.is_none())
                .map(|section| ferrobot_sim::camera_server::CameraOptions {
                    section,
                    seed: 1,
                    noise: world.depth_noise,
                    mount_error: world.mount_error,
                    marker: world.marker,
                });
            let link = match &backend {
                Backend::Emulated { firmware } => crate::backend::emulated::EmulatedLink::start_in(
                    &cfg.name,
                    firmware,
                    world.scene.clone(),
                    camera,
                )?,
                _ => crate::backend::emulated::EmulatedLink::start_host_run(
                    cfg,
                    world.scene.clone(),
                    camera,
                )?,
            };
            let socket = link.camera.as_ref().map(|c| c.path.clone());
            (Box::new(link), socket)
        }
        #[cfg(feature = "direct")]
        Backend::Direct {
            servo,
            base,
            camera,
        } => {
            use crate::backend::direct::{check::Devices, temp_link, DirectLink, HostLink, Ports};
            let ports = Ports {
                host: HostLink::Serve(temp_link("direct")),
                devices: Devices {
                    servo: servo.clone(),
                    base: base.clone(),
                },
                clock: None,
                ticks: None,
            };
            (Box::new(DirectLink::start(cfg, &ports)?), camera.clone())
        }
    };
    let uses_camera = uses_camera && cfg.camera.is_some();
    let camera = match (&cfg.camera, uses_camera, camera_device) {
        (Some(_), true, Some(d)) => Some(d),
        (Some(section), true, None) => {
            backend_camera(&backend, link.as_mut(), section, served_camera, {
                #[cfg(feature = "sim")]
                {
                    &world
                }
                #[cfg(not(feature = "sim"))]
                {
                    &()
                }
            })?
        }
        _ => None,
    };
    Ok(Connected {
        link,
        camera,
        #[cfg(feature = "sim")]
        scene: world.scene,
        #[cfg(feature = "sim")]
        shared: world.shared.map(|(w, _)| w),
    })
}

#[cfg(feature = "sim")]
type WorldRef<'a> = &'a crate::world_options::World;
#[cfg(not(feature = "sim"))]
type WorldRef<'a> = &'a ();

/// The camera device a backend gives: the simulator's renderer on the sim backend, else the
/// camera served beside the link (`served`), else none.
#[allow(unused_variables)]
fn backend_camera(
    backend: &Backend,
    link: &mut dyn Link,
    section: &ferrobot_description::CameraSection,
    served: Option<std::path::PathBuf>,
    world: WorldRef<'_>,
) -> Result<Option<Box<dyn CameraDevice>>> {
    #[cfg(feature = "sim")]
    if let (Backend::Sim { seed, .. }, Some((scene, body))) =
        (backend, crate::backend::world::scene_and_body_of(link))
    {
        return Ok(Some(Box::new(crate::backend::sim::SimCameraDevice::new(
            &scene,
            body.as_ref(),
            section,
            world.depth_noise,
            *seed,
            &world.mount_error,
            world.marker,
        )?)));
    }
    #[cfg(feature = "serial")]
    if let Some(socket) = served {
        return Ok(Some(Box::new(
            crate::backend::camera_socket::SocketCamera::connect(socket)?,
        )));
    }
    Ok(None)
}
