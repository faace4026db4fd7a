"""`hamnet up`: run a stack file (compose/*.yaml) as supervised processes linked by Zenoh;
`hamnet certs`: the certificates such a stack needs to run over mutual TLS."""
