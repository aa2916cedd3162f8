// Placeholder: this file is written by the module's issue.
