"""The cutting station: configuration, job store, daemon and the `station` console command."""
