"""What a deployed policy needs, in numpy only: the manifest beside a NIR file, and the host
side of the policy (observation normalisation, rate encoding with its random generator, the
readout and the action decoding) that training, export and every backend share."""
