//! The MTConnect 2.5 agent's pure part (docs/mtconnect.md): the device model built from the
//! configuration, the observation buffer, what the controller's state says about each data
//! item, the requests, and the four documents (Devices, Streams, Assets, Error) written with
//! `quick-xml`. No clocks, sockets or threads: the HTTP server and the feed task are in
//! `runtime::mtconnect`.

pub mod agent;
pub mod assets;
pub mod buffer;
pub mod devices;
pub mod error;
pub mod fuzz;
pub mod model;
pub mod observe;
pub mod request;
pub mod streams;
pub mod xml;
pub mod xpath;

pub use agent::Agent;
pub use model::{AxisDesc, DeviceModel, MachineDesc};
