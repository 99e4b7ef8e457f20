"""The files a user gives and the package writes: parameter files, specs, shipped data."""
