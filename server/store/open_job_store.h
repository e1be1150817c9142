#pragma once

// The job store a location names (server --store, docs/guide/deploy.md):
//   postgresql://... or postgres://...  PostgreSQL (a libpq connection URI)
//   sqlite:PATH                          SQLite, the database file PATH
// A plain folder (server --store DIR) is SQLite in DIR/render.db; JobManager opens that itself.

#include <memory>
#include <string>

#include "server/job_store.h"

namespace render::server {

// Whether `location` is one of the URLs above (rather than a folder).
bool is_store_url(const std::string& location);

// The file a sqlite: URL names ("" for any other location).
std::string sqlite_url_path(const std::string& location);

// The store `url` names, opened and migrated; std::invalid_argument for a location that is not
// a store URL, std::runtime_error when the database cannot be opened. `connections`: the
// PostgreSQL store's pool size (SQLite has one connection).
std::unique_ptr<JobStore> open_job_store(const std::string& url,
                                         size_t connections = kDefaultStoreConnections);

// `url` fit for logs and messages: a password (user:PASSWORD@ or password=...) replaced by ***.
std::string redact_store_url(const std::string& url);

}  // namespace render::server
