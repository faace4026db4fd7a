"""What every service shares: the Zenoh session, key expressions, the topic contract, typed
publishers and subscribers, tensor codecs, liveliness, health and the service lifecycle."""
