"""Table and figure builders; they read result files and write figures."""
