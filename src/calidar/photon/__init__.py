"""Single-photon lidar (ICESat-2 style): denoising, ground profile, CCR geolocation calibration."""
