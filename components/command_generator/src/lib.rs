//! The command panel: game commands from a web page (CommandGenerator).
