"""Closing the stack to strangers: certificates, mutual TLS and Zenoh access control."""
