//! The simulated person and world of the touch-the-ball game.
