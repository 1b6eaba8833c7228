"""Libraries and forests: many trees from a jobs file, and a forest scattered from a library."""
