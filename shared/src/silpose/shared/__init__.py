"""silpose.shared: conventions every package agrees on (skeleton, cameras, contours, dataset)."""
