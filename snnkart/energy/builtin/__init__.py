"""The built-in hardware profiles (TOML package data; see snnkart.energy.profiles)."""
