//! The path tracer. OWNER: lead.
