//! Serial ports and pseudo-terminals: opening a device path exactly as a
//! real /dev/ttyACM0 is opened, and creating ptys for the emulators.
