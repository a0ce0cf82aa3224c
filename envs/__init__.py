"""What the machine does: printer description, MuJoCo model, simulation, exact linear reference,
metrics, gymnasium environments and identification from accelerometer data."""
