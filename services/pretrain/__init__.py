"""UniCORN pre-training (issue 14): contact pairs on disk, the Siamese encoder with a contact
decoder trained by SAM, and held-out evaluation; `hamnet pretrain generate|train|eval`."""
