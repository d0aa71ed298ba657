"""meshcat views of the robots: served live, or written as self-contained HTML pages."""
