angle factor: 18
