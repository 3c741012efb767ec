"""dtdyn runtime."""
